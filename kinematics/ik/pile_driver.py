"""Closed-form IK of the side-clamp pile-driver arm by matrix inversion (paper 000, eqs. 3-17).

The arm (Table 1, modified D-H): a swing joint, three parallel pitch joints (boom, stick,
four-bar linkage), then a tilt joint with offsets L4, L5 and a rotator. The tool position
depends on joints 1-4 only; the orientation fixes theta_234 = theta2 + theta3 + theta4,
theta5 and theta6.

Following the paper: premultiplying the target by ``T01^-1`` (eq. 3) and equating the (2, 4)
elements gives theta1 (eq. 5); the rotation part of ``T01^-1 T06`` then gives theta_234,
theta5 and theta6 (eqs. 8-12, 15-16); the planar two-link problem gives theta3 (eqs. 6-7) and
theta2 (eq. 14); eq. 17 closes theta4. Corrections to the printed algebra:

* eq. 7 prints ``c3 = (m1 + m2)/2 * L2 * L3``; the law of cosines needs a division,
  ``c3 = (m1 + m2) / (2 L2 L3)``.
* eqs. 10, 12 and 16 are derived from the paper's printed ``p``/``n, o, a`` expressions,
  which do not follow from Table 1 (its p_x at q = 0 is L1+L2+L3+L5, not the printed 190 cm)
  and so give wrong angles. We take the same matrix elements from the model of Table 1
  itself: ``Rz(-theta1) R RotX(-alpha1) = Rz(theta_234) RotX(alpha4) Rz(theta5) RotX(alpha5)
  Rz(theta6)``, a Z-Y-Z Euler problem.
* eq. 14's ``s2`` is divided by ``L3 s3`` and so fails at s3 = 0 (stick in line with the
  boom); the equivalent ``theta2 = atan2(k2, k1) - atan2(L3 s3, L2 + L3 c3)`` does not.
* eq. 5 gives one theta1; ``theta1 + pi`` with the arm reaching backwards is the second
  shoulder branch. With theta5 = 0 the tilt and rotator axes align (a singularity): only
  theta_234 - theta6 is determined, and theta_234 is taken from ``q0``.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..fast import c_array, kernels, pile_data
from ..model import RobotModel
from ._wrist import has_6r_structure, reduce_targets, rx, rz, wrist_angles
from .result import IKResult, finish_analytic, finish_one

__all__ = ["supports", "solve"]

METHOD = "analytic:pile_driver"
#: Candidate theta_234 values tried across the circle when the wrist is singular.
SINGULAR_SWEEP = 360


def supports(model: RobotModel) -> bool:
    """Whether ``model`` has the pile-driver structure (three parallel pitch joints, offset
    tilt joint, rotator)."""
    return has_6r_structure(model, right_angle=(1, 4, 5), parallel=(2, 3), zero_a=(5,),
                            zero_d=(1, 2, 3, 5))


def solve(
    model: RobotModel, T_target: np.ndarray, q0: np.ndarray | None = None
) -> list[IKResult]:
    """Every IK branch for rigid targets ``T_world_tool (B, 4, 4)`` (world frame, mm);
    one ``IKResult`` per target. On the compiled kernels (``kinematics.fast``) one target at a
    time, else all targets at once in numpy."""
    K = kernels()
    if K is not None:
        return [_solve_one(K, model, T, q0) for T in T_target]
    j = model.joints
    B = T_target.shape[0]
    off = np.array([jt.offset for jt in j])
    hint = q0 if q0 is not None else model.mid_configuration()
    hint_234 = float(np.sum(hint[1:4] + off[1:4]))
    G = reduce_targets(model, T_target)
    px, py, pz = G[:, 0, 3], G[:, 1, 3], G[:, 2, 3]
    sa1 = math.copysign(1.0, math.sin(j[1].alpha))
    L1, L2, L3, L4 = j[1].a, j[2].a, j[3].a, j[4].a
    d1, L5 = j[0].d, j[4].d
    # Tool point seen from frame 4 (before the tilt joint): (L4, -sin(alpha4) L5).
    w4x, w4y = L4, -math.sin(j[4].alpha) * L5
    cb = round(math.cos(j[4].alpha + j[5].alpha))

    # eq. 5: theta1 = atan2(py, px) (the arm has no sideways offset); + pi reaches backwards.
    on_axis = np.hypot(px, py) < 1e-9
    t1 = np.arctan2(py, px)[:, None] + np.array([0.0, math.pi])  # (B, 2)
    t1[on_axis] = hint[0] + off[0]

    # eq. 3: T01^-1 T06; its rotation, less the boom's twist, is the wrist problem.
    N = rx(-j[1].alpha) @ np.swapaxes(rz(t1), -1, -2) @ G[:, None, :3, :3]
    t234, t5, t6, wsing = wrist_angles(
        N.reshape(-1, 3, 3), j[4].alpha, j[5].alpha, np.full(2 * B, hint_234)
    )
    owner = np.repeat(np.arange(B), 4)  # (B * 2 shoulder * 2 wrist)
    cand = np.stack([np.repeat(t1.reshape(-1), 2), t234.reshape(-1), t5.reshape(-1),
                     t6.reshape(-1)], axis=1)
    if wsing.any():
        # Any theta_234 of the family will do for the orientation; the position and the
        # limits decide. Try the hint, then a fine sweep of the whole circle.
        rows = np.flatnonzero(np.repeat(wsing, 2))
        dt = np.concatenate([[0.0], np.linspace(-math.pi, math.pi, SINGULAR_SWEEP,
                                                endpoint=False)])
        sweep = np.repeat(cand[rows], len(dt), axis=0)
        shift = np.tile(dt, len(rows))
        sweep[:, 1] += shift
        sweep[:, 3] -= cb * shift
        cand = np.concatenate([cand, sweep])
        owner = np.concatenate([owner, np.repeat(owner[rows], len(dt))])

    c1, s1 = np.cos(cand[:, 0]), np.sin(cand[:, 0])
    c234, s234 = np.cos(cand[:, 1]), np.sin(cand[:, 1])
    # k1, k2 of eq. 14: the planar position of the stick tip (frame 4 origin).
    k1 = c1 * px[owner] + s1 * py[owner] - L1 - (c234 * w4x - s234 * w4y)
    k2 = (pz[owner] - d1) / sa1 - (s234 * w4x + c234 * w4y)
    # eq. 7, corrected: c3 = (m1 + m2) / (2 L2 L3).
    c3 = (k1 * k1 + k2 * k2 - L2 * L2 - L3 * L3) / (2 * L2 * L3)
    c3 = np.where(np.abs(c3) > 1 + 1e-12, np.nan, np.clip(c3, -1.0, 1.0))
    s3 = np.sqrt(1.0 - c3 * c3)[:, None] * np.array([1.0, -1.0])  # eq. 7, both elbows
    c3b = np.broadcast_to(c3[:, None], s3.shape)
    t3 = np.arctan2(s3, c3b)  # eq. 6
    t2 = np.arctan2(k2, k1)[:, None] - np.arctan2(L3 * s3, L2 + L3 * c3b)  # eq. 14
    t4 = cand[:, 1, None] - t2 - t3  # eq. 17
    rep = lambda col: np.broadcast_to(cand[:, col, None], t2.shape)  # noqa: E731
    branches = np.stack([rep(0), t2, t3, t4, rep(2), rep(3)], axis=-1).reshape(-1, 6) - off
    owner2 = np.repeat(owner, 2)

    reasons: list[str | None] = [None] * B
    reach = np.hypot(k1, k2)
    for b in range(B):
        mine = owner == b
        if np.all(np.isnan(c3[mine])):
            reasons[b] = _out_of_reach(float(reach[mine].min()), L2, L3)
    singular = on_axis | wsing.reshape(B, 2).any(axis=1)
    return finish_analytic(
        model, T_target, branches, owner2, METHOD, q0, reasons=reasons, singular=singular
    )


def _out_of_reach(reach: float, L2: float, L3: float) -> str:
    return (f"the stick tip would be {reach:.1f} mm from the boom pivot at best, outside "
            f"[{abs(L2 - L3):.1f}, {L2 + L3:.1f}] mm")


def _solve_one(K, model: RobotModel, T: np.ndarray, q0: np.ndarray | None) -> IKResult:
    """``solve`` for one target ``(4, 4)`` on the compiled kernels: the same branches
    (``_kernels.pile_branches``), checked and ordered by ``finish_one``."""
    p, rx_m1, rx_ab, pre_inv, tool_inv, off = pile_data(model)
    hint = _hint(model) if q0 is None else _hints(np.asarray(q0, dtype=float), off)
    T = c_array(T)
    diag = np.empty(3)
    branches = K.pile_branches(p, rx_m1, rx_ab, pre_inv, tool_inv, off, T, *hint, diag)
    reason = _out_of_reach(float(diag[2]), float(p[2]), float(p[3])) if diag[1] else None
    return finish_one(K, model, T, branches, METHOD, q0, reason=reason,
                      singular=bool(diag[0]))


def _hints(q: np.ndarray, off: np.ndarray) -> tuple[float, float]:
    """theta1 and theta_234 of ``q`` (offsets added): the choices at a singularity."""
    return float(q[0] + off[0]), float(np.sum(q[1:4] + off[1:4]))


@lru_cache(maxsize=64)
def _hint(model: RobotModel) -> tuple[float, float]:
    """``_hints`` of the middle of the limits, used when no ``q0`` is given."""
    return _hints(model.mid_configuration(), pile_data(model)[-1])
