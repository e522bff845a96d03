"""Pieces shared by the closed-form solvers of 6R arms described in modified D-H."""

from __future__ import annotations

import math

import numpy as np

from ..model import RobotModel
from ..transforms import invert_pose, rot_x, trans

HALF_PI = math.pi / 2
#: |sin| of the middle wrist angle below which the wrist counts as singular.
WRIST_SINGULAR_TOL = 1e-9


def is_right_angle(alpha: float) -> bool:
    return abs(abs(alpha) - HALF_PI) < 1e-9


def is_zero(x: float) -> bool:
    return abs(x) < 1e-9


def reduce_target(model: RobotModel, T_target: np.ndarray) -> np.ndarray:
    """Target tool pose -> pose of the last link frame in the frame just before joint 1's
    rotation: ``(base RotX(alpha_0) TransX(a_0))^-1 T_target tool^-1``."""
    j1 = model.joints[0]
    pre = model.base @ rot_x(j1.alpha) @ trans(j1.a)
    return invert_pose(pre) @ T_target @ invert_pose(model.tool)


def wrist_angles(
    M: np.ndarray, alpha_a: float, alpha_b: float, first_hint: float
) -> tuple[list[tuple[float, float, float]], bool]:
    """Solve ``M = Rz(t1) RotX(alpha_a) Rz(t2) RotX(alpha_b) Rz(t3)`` for (t1, t2, t3).

    With both twists at ±90° this is a Z-Y-Z Euler decomposition:
    ``RotX(a) Rz(t2) = RotY(-sin(a) t2) RotX(a)`` and
    ``RotX(a+b) Rz(t3) = Rz(cos(a+b) t3) RotX(a+b)``, so
    ``M RotX(-(a+b)) = Rz(t1) RotY(-sin(a) t2) Rz(cos(a+b) t3)``. Two branches in general;
    at the singularity (t2 = 0 or pi) only t1 ± t3 is fixed and ``first_hint`` sets t1.
    Returns the branches and whether the wrist is singular.
    """
    sa = math.copysign(1.0, math.sin(alpha_a))
    cb = round(math.cos(alpha_a + alpha_b))
    Mp = M[:3, :3] @ rot_x(-(alpha_a + alpha_b))[:3, :3]
    sb_abs = math.hypot(Mp[0, 2], Mp[1, 2])
    out = []
    if sb_abs < WRIST_SINGULAR_TOL:
        if Mp[2, 2] > 0:  # b = 0: Mp = Rz(a + c)
            b, a = 0.0, first_hint
            c = math.atan2(Mp[1, 0], Mp[0, 0]) - a
        else:  # b = pi: Mp = Rz(a) RotY(pi) Rz(c) = Rz(a - c) RotY(pi)
            b, a = math.pi, first_hint
            c = a - math.atan2(-Mp[1, 0], -Mp[0, 0])
        out.append((a, -sa * b, cb * c))
        return out, True
    for sign in (1.0, -1.0):
        sb = sign * sb_abs
        b = math.atan2(sb, Mp[2, 2])
        a = math.atan2(Mp[1, 2] / sb, Mp[0, 2] / sb)
        c = math.atan2(Mp[2, 1] / sb, -Mp[2, 0] / sb)
        out.append((a, -sa * b, cb * c))
    return out, False


def wrap(angle: float) -> float:
    """Angle into (-pi, pi]."""
    return math.atan2(math.sin(angle), math.cos(angle))
