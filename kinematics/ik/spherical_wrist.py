"""Closed-form IK of 6R arms with a spherical wrist (the GLT palletizer and its kin).

Applies to modified D-H chains with joint 2 at a right angle to joint 1's frame
(alpha_1 = ±90°), joints 2 and 3 parallel (alpha_2 = 0), the forearm twisted by ±90°
(alpha_3), and the last three axes meeting in one point (a_4 = a_5 = 0, d_5 = d_6 = 0,
alpha_4 = alpha_5 = ±90°). Joint 1's own twist and length, d_1 and a shoulder offset
d_2 + d_3 are all allowed.

Method (Pieper): the wrist centre fixes joints 1-3 (two shoulder x two elbow branches), the
orientation left over fixes 4-6 (two wrist branches): up to eight branches, each then
repeated over the extra turns that joints with ranges past ±180° allow.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..fast import c_array, kernels, wrist_data
from ..model import RobotModel
from ._wrist import has_6r_structure, reduce_targets, rx, rz, wrist_angles
from .result import IKResult, finish_analytic, finish_one

__all__ = ["supports", "solve"]

METHOD = "analytic:spherical_wrist"


def supports(model: RobotModel) -> bool:
    """Whether ``model`` has the structure this solver needs."""
    return has_6r_structure(model, right_angle=(1, 3, 4, 5), parallel=(2,), zero_a=(4, 5),
                            zero_d=(4, 5))


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
    G = reduce_targets(model, T_target)
    Px, Py, Pz = G[:, 0, 3], G[:, 1, 3], G[:, 2, 3]
    sa1 = math.copysign(1.0, math.sin(j[1].alpha))
    a1, a2, a3 = j[1].a, j[2].a, j[3].a
    d1, lateral = j[0].d, j[1].d + j[2].d
    # Wrist centre seen from frame 3: (a3, -sin(alpha3) d4).
    w3x, w3y = a3, -math.sin(j[3].alpha) * j[3].d
    rho = math.hypot(w3x, w3y)
    psi = math.atan2(w3y, w3x)

    # Joint 1: the wrist centre must lie in the arm plane, offset by -sin(alpha1)(d2 + d3).
    e = -sa1 * lateral
    R_xy = np.hypot(Px, Py)
    on_axis = R_xy < 1e-9  # wrist centre on joint 1's axis: any joint 1 angle will do
    too_close = R_xy < abs(e) - 1e-9
    asin = np.arcsin(np.clip(e / np.where(on_axis, 1.0, R_xy), -1.0, 1.0))
    phi = np.arctan2(Py, Px)
    t1 = np.stack([phi - asin, phi - math.pi + asin], axis=1)  # (B, 2) shoulder branches
    t1[on_axis] = hint[0] + off[0]
    t1[too_close] = np.nan

    c1, s1 = np.cos(t1), np.sin(t1)
    X = c1 * Px[:, None] + s1 * Py[:, None] - a1
    Y = np.broadcast_to(((Pz - d1) / sa1)[:, None], X.shape)
    K = (X * X + Y * Y - a2 * a2 - rho * rho) / (2 * a2 * rho)
    K = np.where(np.abs(K) > 1 + 1e-12, np.nan, np.clip(K, -1.0, 1.0))
    elbow = np.array([1.0, -1.0])
    t3 = -psi + elbow * np.arccos(K)[..., None]  # (B, 2, 2): shoulder x elbow
    u = a2 + np.cos(t3) * w3x - np.sin(t3) * w3y
    v = np.sin(t3) * w3x + np.cos(t3) * w3y
    t2 = np.arctan2(Y, X)[..., None] - np.arctan2(v, u)
    t1b = np.broadcast_to(t1[..., None], t2.shape)

    R03 = rz(t1b) @ rx(j[1].alpha) @ rz(t2 + t3)
    M = rx(-j[3].alpha) @ np.swapaxes(R03, -1, -2) @ G[:, None, None, :3, :3]
    t4, t5, t6, wsing = wrist_angles(
        M.reshape(-1, 3, 3), j[4].alpha, j[5].alpha, np.full(4 * B, hint[3] + off[3])
    )
    arm = np.stack([t1b, t2, t3], axis=-1).reshape(-1, 1, 3)  # (4B, 1, 3)
    branches = np.concatenate(
        [np.broadcast_to(arm, (4 * B, 2, 3)), np.stack([t4, t5, t6], axis=-1)], axis=-1
    ).reshape(-1, 6) - off
    owner = np.repeat(np.arange(B), 8)
    singular = on_axis | wsing.reshape(B, 4).any(axis=1)

    reasons: list[str | None] = [None] * B
    for b in np.flatnonzero(too_close):
        reasons[b] = _too_close(float(R_xy[b]), e)
    for b in np.flatnonzero(~too_close & np.all(np.isnan(K), axis=1)):
        reasons[b] = _out_of_reach(float(np.hypot(X[b, 0], Y[b, 0])), a2, rho)
    return finish_analytic(
        model, T_target, branches, owner, METHOD, q0, reasons=reasons, singular=singular
    )


def _too_close(r_xy: float, e: float) -> str:
    return (f"the wrist centre is {r_xy:.3f} mm from the axis of joint 1, closer than the "
            f"shoulder offset {abs(e):.3f} mm")


def _out_of_reach(dist: float, a2: float, rho: float) -> str:
    return (f"the wrist centre is {dist:.1f} mm from the shoulder axis, outside the arm's "
            f"reach [{abs(a2 - rho):.1f}, {a2 + rho:.1f}] mm")


def _solve_one(K, model: RobotModel, T: np.ndarray, q0: np.ndarray | None) -> IKResult:
    """``solve`` for one target ``(4, 4)`` on the compiled kernels: the same branches
    (``_kernels.wrist_branches``), checked and ordered by ``finish_one``."""
    p, rx_a1, rx_m3, rx_ab, pre_inv, tool_inv, off = wrist_data(model)
    hint = _hint(model) if q0 is None else (float(q0[0] + off[0]), float(q0[3] + off[3]))
    T = c_array(T)
    diag = np.empty(5)
    branches = K.wrist_branches(p, rx_a1, rx_m3, rx_ab, pre_inv, tool_inv, off, T, *hint,
                                diag)
    reason = None
    if diag[1]:
        reason = _too_close(float(diag[2]), float(p[8]))
    elif diag[3]:
        reason = _out_of_reach(float(diag[4]), float(p[2]), float(p[4]))
    return finish_one(K, model, T, branches, METHOD, q0, reason=reason,
                      singular=bool(diag[0]))


@lru_cache(maxsize=64)
def _hint(model: RobotModel) -> tuple[float, float]:
    """Joint 1 and 4 angles (offsets added) of the middle of the limits: the choice at a
    singularity when no ``q0`` is given."""
    mid = model.mid_configuration()
    return (float(mid[0] + model.joints[0].offset), float(mid[3] + model.joints[3].offset))
