"""Geometric Jacobian and the dexterity measures built on it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fk import batch_of, joint_axes
from .model import RobotModel

__all__ = ["jacobian", "jacobian_and_pose", "Dexterity", "dexterity"]


def jacobian_and_pose(model: RobotModel, q) -> tuple[np.ndarray, np.ndarray]:
    """Geometric Jacobian and tool pose: ``q: (*, dof) -> ((*, 6, dof), (*, 4, 4))``.

    Rows are (vx, vy, vz) of the tool point in mm per joint unit, then (wx, wy, wz) in rad
    per joint unit, all in the world frame in which ``fk`` reports ``T_world_tool``
    (docs/conventions.md).
    """
    q2, lead = batch_of(model, q)
    axes, points, T_tool = joint_axes(model, q2)
    p_tool = T_tool[:, None, :3, 3]
    rev = model.revolute[None, :, None]
    lin = np.where(rev, np.cross(axes, p_tool - points), axes)
    ang = np.where(rev, axes, 0.0)
    J = np.concatenate([np.swapaxes(lin, 1, 2), np.swapaxes(ang, 1, 2)], axis=1)
    return J.reshape(lead + (6, model.dof)), T_tool.reshape(lead + (4, 4))


def jacobian(model: RobotModel, q) -> np.ndarray:
    """Geometric Jacobian ``q: (*, dof) -> (*, 6, dof)``, rows (v, ω), world frame."""
    return jacobian_and_pose(model, q)[0]


@dataclass(frozen=True)
class Dexterity:
    """Dexterity measures of one configuration.

    ``manipulability`` is Yoshikawa's sqrt(det(J J^T)) of the raw Jacobian (mm and rad
    mixed, so compare it only between configurations of one robot). ``condition`` and
    ``min_singular_value`` are taken on the unit-normalised Jacobian, whose linear rows are
    divided by the robot's ``length_scale``; ``condition`` is ``inf`` at a singularity.
    """

    manipulability: float
    condition: float
    min_singular_value: float


def dexterity(model: RobotModel, J: np.ndarray) -> Dexterity:
    """Dexterity of one Jacobian ``(6, dof)``."""
    J = np.asarray(J, dtype=float)
    # sqrt(det(J Jᵀ)) is the product of J's singular values (0 with fewer than 6 joints); from
    # the SVD it needs no determinant, whose LU step can divide by zero at extreme values.
    sv_raw = np.linalg.svd(J, compute_uv=False)
    manip = float(np.prod(sv_raw[:6])) if J.shape[1] >= J.shape[0] else 0.0
    Jn = J.copy()
    Jn[:3] /= model.length_scale
    sv = np.linalg.svd(Jn, compute_uv=False)
    rank_dim = min(J.shape)
    smin = float(sv[rank_dim - 1]) if rank_dim else 0.0
    cond = float(sv[0] / smin) if smin > 1e-12 * max(sv[0], 1e-300) else float("inf")
    return Dexterity(manipulability=manip, condition=cond, min_singular_value=smin)
