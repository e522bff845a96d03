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

import numpy as np

from ..model import RobotModel
from ..transforms import rot_x, rot_z
from ._wrist import is_right_angle, is_zero, reduce_target, wrist_angles
from .result import IKResult, finish_analytic

__all__ = ["supports", "solve"]

METHOD = "analytic:pile_driver"
#: Candidate theta_234 values tried across the circle when the wrist is singular.
SINGULAR_SWEEP = 360


def supports(model: RobotModel) -> bool:
    """Whether ``model`` has the pile-driver structure (three parallel pitch joints, offset
    tilt joint, rotator)."""
    if model.convention != "mdh" or model.dof != 6 or not all(model.revolute):
        return False
    j = model.joints
    return (
        is_right_angle(j[1].alpha)
        and is_zero(j[2].alpha)
        and is_zero(j[3].alpha)
        and is_right_angle(j[4].alpha)
        and is_right_angle(j[5].alpha)
        and is_zero(j[5].a)
        and is_zero(j[5].d)
        and all(is_zero(j[i].d) for i in (1, 2, 3))
    )


def solve(model: RobotModel, T_target: np.ndarray, q0: np.ndarray | None = None) -> IKResult:
    """All IK branches for one rigid target pose ``(4, 4)`` (tool frame, base frame, mm)."""
    j = model.joints
    off = np.array([jt.offset for jt in j])
    hint = q0 if q0 is not None else model.mid_configuration()
    hint_234 = float(np.sum(hint[1:4] + off[1:4]))
    G = reduce_target(model, T_target)
    px, py, pz = G[:3, 3]
    sa1 = math.copysign(1.0, math.sin(j[1].alpha))
    L1, L2, L3, L4 = j[1].a, j[2].a, j[3].a, j[4].a
    d1, L5 = j[0].d, j[4].d
    # Tool point seen from frame 4 (before the tilt joint): (L4, -sin(alpha4) L5).
    w4x, w4y = L4, -math.sin(j[4].alpha) * L5

    # eq. 5: theta1 = atan2(py, px) (the arm has no sideways offset); + pi reaches backwards.
    singular = False
    if math.hypot(px, py) < 1e-9:
        singular = True
        theta1s = [hint[0] + off[0]]
    else:
        theta1s = [math.atan2(py, px), math.atan2(py, px) + math.pi]

    branches = []
    reasons = []
    for t1 in theta1s:
        # eq. 3: T01^-1 T06; its rotation, less the boom's twist, is the wrist problem.
        N = rot_x(-j[1].alpha)[:3, :3] @ rot_z(-t1)[:3, :3] @ G[:3, :3]
        wrists, wsing = wrist_angles(N, j[4].alpha, j[5].alpha, hint_234)
        if wsing:
            # Any theta_234 of the family will do for the orientation; the position and the
            # limits decide. Try the hint first, then a fine sweep of the whole circle.
            singular = True
            t_a, t_5, t_6 = wrists[0]
            sweep = hint_234 + np.linspace(-math.pi, math.pi, SINGULAR_SWEEP, endpoint=False)
            wrists = [(t_a + dt, t_5, t_6 - math.cos(j[4].alpha + j[5].alpha) * dt)
                      for dt in np.concatenate([[0.0], sweep - hint_234])]
        for t234, t5, t6 in wrists:
            # k1, k2 of eq. 14: the planar position of the stick tip (frame 4 origin).
            c234, s234 = math.cos(t234), math.sin(t234)
            k1 = math.cos(t1) * px + math.sin(t1) * py - L1 - (c234 * w4x - s234 * w4y)
            k2 = (pz - d1) / sa1 - (s234 * w4x + c234 * w4y)
            # eq. 7, corrected: c3 = (m1 + m2) / (2 L2 L3).
            c3 = (k1 * k1 + k2 * k2 - L2 * L2 - L3 * L3) / (2 * L2 * L3)
            if abs(c3) > 1 + 1e-12:
                reasons.append(
                    f"the stick tip would be {math.hypot(k1, k2):.1f} mm from the boom pivot, "
                    f"outside [{abs(L2 - L3):.1f}, {L2 + L3:.1f}] mm"
                )
                continue
            c3 = max(-1.0, min(1.0, c3))
            for sign in (1.0, -1.0):
                s3 = sign * math.sqrt(1.0 - c3 * c3)  # eq. 7
                t3 = math.atan2(s3, c3)  # eq. 6
                t2 = math.atan2(k2, k1) - math.atan2(L3 * s3, L2 + L3 * c3)  # eq. 14
                t4 = t234 - t2 - t3  # eq. 17
                branches.append(np.array([t1, t2, t3, t4, t5, t6]) - off)
    reason = reasons[0] if reasons else None
    return finish_analytic(
        model, T_target, np.array(branches).reshape(-1, 6), METHOD, q0,
        unreachable_reason=reason, singular=singular,
    )
