"""Pieces shared by the closed-form solvers of 6R arms described in modified D-H.

Everything here is batched: one row per (target pose, branch).
"""

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


def has_6r_structure(model: RobotModel, *, right_angle: tuple[int, ...],
                     parallel: tuple[int, ...], zero_a: tuple[int, ...] = (),
                     zero_d: tuple[int, ...] = ()) -> bool:
    """Whether ``model`` is a 6R arm in modified D-H whose joints (0-based) in
    ``right_angle`` have alpha = +-90 deg, in ``parallel`` alpha = 0, and whose ``zero_a`` /
    ``zero_d`` joints have a = 0 / d = 0: the structure a closed-form solver relies on."""
    if model.convention != "mdh" or model.dof != 6 or not all(model.revolute):
        return False
    j = model.joints
    return (all(is_right_angle(j[i].alpha) for i in right_angle)
            and all(is_zero(j[i].alpha) for i in parallel)
            and all(is_zero(j[i].a) for i in zero_a)
            and all(is_zero(j[i].d) for i in zero_d))


def reduce_targets(model: RobotModel, T_target: np.ndarray) -> np.ndarray:
    """Target tool poses ``(B, 4, 4)`` -> poses of the last link frame in the frame just
    before joint 1's rotation: ``(base RotX(alpha_0) TransX(a_0))^-1 T_target tool^-1``."""
    j1 = model.joints[0]
    pre = model.base @ rot_x(j1.alpha) @ trans(j1.a)
    return invert_pose(pre) @ T_target @ invert_pose(model.tool)


def rz(theta: np.ndarray) -> np.ndarray:
    """Rotations about z ``(*,) -> (*, 3, 3)``."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(np.shape(theta) + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = c, -s, s, c
    R[..., 2, 2] = 1.0
    return R


def rx(alpha: float) -> np.ndarray:
    """Rotation about x by a constant ``(3, 3)``."""
    return rot_x(alpha)[:3, :3]


def wrist_angles(
    M: np.ndarray, alpha_a: float, alpha_b: float, first_hint: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Solve ``M = Rz(t1) RotX(alpha_a) Rz(t2) RotX(alpha_b) Rz(t3)`` for rows ``M (R, 3, 3)``.

    With both twists at ±90° this is a Z-Y-Z Euler decomposition:
    ``RotX(a) Rz(t2) = RotY(-sin(a) t2) RotX(a)`` and
    ``RotX(a+b) Rz(t3) = Rz(cos(a+b) t3) RotX(a+b)``, so
    ``M RotX(-(a+b)) = Rz(t1) RotY(-sin(a) t2) Rz(cos(a+b) t3)``.

    Returns ``t1, t2, t3`` of shape ``(R, 2)`` (the two branches) and ``singular (R,)``. At the
    singularity (t2 = 0 or pi) only t1 ± t3 is fixed: ``first_hint (R,)`` sets t1 and both
    columns hold the same solution.
    """
    sa = math.copysign(1.0, math.sin(alpha_a))
    cb = round(math.cos(alpha_a + alpha_b))
    Mp = M @ rx(-(alpha_a + alpha_b))
    sb_abs = np.hypot(Mp[:, 0, 2], Mp[:, 1, 2])
    singular = sb_abs < WRIST_SINGULAR_TOL
    sign = np.array([1.0, -1.0])
    sb = np.where(singular, 1.0, sb_abs)[:, None] * sign  # placeholder 1 where singular
    b = np.arctan2(sb, Mp[:, 2, 2, None])
    a = np.arctan2(Mp[:, 1, 2, None] / sb, Mp[:, 0, 2, None] / sb)
    c = np.arctan2(Mp[:, 2, 1, None] / sb, -Mp[:, 2, 0, None] / sb)
    if singular.any():
        up = Mp[singular, 2, 2] > 0
        hint = first_hint[singular]
        # b = 0: Mp = Rz(a + c).  b = pi: Mp = Rz(a - c) RotY(pi).
        c_up = np.arctan2(Mp[singular, 1, 0], Mp[singular, 0, 0]) - hint
        c_down = hint - np.arctan2(-Mp[singular, 1, 0], -Mp[singular, 0, 0])
        b[singular] = np.where(up, 0.0, math.pi)[:, None]
        a[singular] = hint[:, None]
        c[singular] = np.where(up, c_up, c_down)[:, None]
    return a, -sa * b, cb * c, singular
