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

import numpy as np

from ..model import RobotModel
from ..transforms import rot_x, rot_z
from ._wrist import is_right_angle, is_zero, reduce_target, wrist_angles
from .result import IKResult, finish_analytic

__all__ = ["supports", "solve"]

METHOD = "analytic:spherical_wrist"


def supports(model: RobotModel) -> bool:
    """Whether ``model`` has the structure this solver needs."""
    if model.convention != "mdh" or model.dof != 6 or not all(model.revolute):
        return False
    j = model.joints
    return (
        is_right_angle(j[1].alpha)
        and is_zero(j[2].alpha)
        and is_right_angle(j[3].alpha)
        and is_right_angle(j[4].alpha)
        and is_right_angle(j[5].alpha)
        and is_zero(j[4].a)
        and is_zero(j[5].a)
        and is_zero(j[4].d)
        and is_zero(j[5].d)
    )


def solve(model: RobotModel, T_target: np.ndarray, q0: np.ndarray | None = None) -> IKResult:
    """All IK branches for one rigid target pose ``(4, 4)`` (tool frame, base frame, mm)."""
    j = model.joints
    off = np.array([jt.offset for jt in j])
    hint = q0 if q0 is not None else model.mid_configuration()
    G = reduce_target(model, T_target)
    Px, Py, Pz = G[:3, 3]
    sa1 = math.copysign(1.0, math.sin(j[1].alpha))
    a1, a2, a3 = j[1].a, j[2].a, j[3].a
    d1, lateral = j[0].d, j[1].d + j[2].d
    # Wrist centre seen from frame 3: (a3, -sin(alpha3) d4).
    w3x, w3y = a3, -math.sin(j[3].alpha) * j[3].d
    rho = math.hypot(w3x, w3y)
    psi = math.atan2(w3y, w3x)

    # Joint 1: the wrist centre must lie in the arm plane, offset by -sin(alpha1)(d2 + d3).
    e = -sa1 * lateral
    R_xy = math.hypot(Px, Py)
    singular = False
    if R_xy < abs(e) - 1e-9:
        return finish_analytic(
            model, T_target, np.empty((0, 6)), METHOD, q0,
            unreachable_reason=f"the wrist centre is {R_xy:.3f} mm from the axis of joint 1, "
            f"closer than the shoulder offset {abs(e):.3f} mm",
        )
    if R_xy < 1e-9:
        singular = True  # wrist centre on joint 1's axis: any joint 1 angle will do
        theta1s = [hint[0] + off[0]]
    else:
        phi = math.atan2(Py, Px)
        s = math.asin(max(-1.0, min(1.0, e / R_xy)))
        theta1s = [phi - s, phi - math.pi + s]

    branches = []
    reasons = []
    for t1 in theta1s:
        c1, s1 = math.cos(t1), math.sin(t1)
        X = c1 * Px + s1 * Py - a1
        Y = (Pz - d1) / sa1
        K = (X * X + Y * Y - a2 * a2 - rho * rho) / (2 * a2 * rho)
        if abs(K) > 1 + 1e-12:
            dist = math.hypot(X, Y)
            reasons.append(
                f"the wrist centre is {dist:.1f} mm from the shoulder axis, outside the "
                f"arm's reach [{abs(a2 - rho):.1f}, {a2 + rho:.1f}] mm"
            )
            continue
        K = max(-1.0, min(1.0, K))
        for elbow in (1.0, -1.0):
            t3 = -psi + elbow * math.acos(K)
            u = a2 + math.cos(t3) * w3x - math.sin(t3) * w3y
            v = math.sin(t3) * w3x + math.cos(t3) * w3y
            t2 = math.atan2(Y, X) - math.atan2(v, u)
            R03 = (rot_z(t1) @ rot_x(j[1].alpha) @ rot_z(t2) @ rot_z(t3))[:3, :3]
            M = rot_x(-j[3].alpha)[:3, :3] @ R03.T @ G[:3, :3]
            wrists, wsing = wrist_angles(M, j[4].alpha, j[5].alpha, hint[3] + off[3])
            singular = singular or wsing
            for t4, t5, t6 in wrists:
                branches.append(np.array([t1, t2, t3, t4, t5, t6]) - off)
    reason = reasons[0] if reasons else None
    return finish_analytic(
        model, T_target, np.array(branches).reshape(-1, 6), METHOD, q0,
        unreachable_reason=reason, singular=singular,
    )
