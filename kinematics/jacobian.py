"""Geometric Jacobian and the dexterity measures built on it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .fast import chain_of, jacobian_rows, kernels
from .fk import batch_of, joint_axes
from .model import RobotModel

__all__ = ["jacobian", "jacobian_and_pose", "PositionJacobian", "Dexterity", "dexterity"]


def jacobian_and_pose(model: RobotModel, q) -> tuple[np.ndarray, np.ndarray]:
    """Geometric Jacobian and tool pose: ``q: (*, dof) -> ((*, 6, dof), (*, 4, 4))``.

    Rows are (vx, vy, vz) of the tool point in mm per joint unit, then (wx, wy, wz) in rad
    per joint unit, all in the world frame in which ``fk`` reports ``T_world_tool``
    (docs/conventions.md). Runs on the compiled kernels when they are available
    (``kinematics.fast``), else on numpy.
    """
    K = kernels()
    if K is not None and type(q) is np.ndarray and q.shape == (model.dof,) and \
            q.dtype == np.float64 and q.flags.c_contiguous and q.flags.writeable:
        # One configuration as the kernel takes it: no normalisation to pay for.
        ch = chain_of(model)
        J, T = np.empty((6, model.dof)), np.empty((4, 4))
        K.jacobian_pose(ch.C, ch.prismatic, ch.offset, q, J, T)
        return J, T
    q2, lead = batch_of(model, q)
    if K is not None:
        J, T_tool = jacobian_rows(K, model, q2)
        return J.reshape(lead + (6, model.dof)), T_tool.reshape(lead + (4, 4))
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


class PositionJacobian:
    """Tool position and position Jacobian, batched: ``q (P, dof) -> ((P, 3), (P, 3, dof))``
    (mm and mm/rad, world frame; the first three rows of ``jacobian``).

    Built once per model, called many times (a controller calls it at every step). For
    all-revolute product-of-exponentials models (the 9-DOF arm) the chain is composed by a
    parallel (Hillis-Steele) prefix product over the joints, about twice as fast as the
    general ``jacobian_and_pose``; other models use that function. Both agree to rounding
    (tested).
    """

    def __init__(self, model: RobotModel) -> None:
        self.model = model
        self.fast = model.convention == "poe" and bool(np.all(model.revolute))
        if not self.fast:
            return
        w = np.array([j.axis for j in model.joints], dtype=float)
        self._w = w / np.linalg.norm(w, axis=1, keepdims=True)
        self._p = np.array([j.point if j.point is not None else (0.0, 0.0, 0.0)
                            for j in model.joints], dtype=float)
        self._offset = np.array([j.offset for j in model.joints], dtype=float)
        K = np.zeros((model.dof, 3, 3))
        K[:, 0, 1], K[:, 0, 2] = -self._w[:, 2], self._w[:, 1]
        K[:, 1, 0], K[:, 1, 2] = self._w[:, 2], -self._w[:, 0]
        K[:, 2, 0], K[:, 2, 1] = -self._w[:, 1], self._w[:, 0]
        self._K, self._K2 = K, K @ K
        self._Kp = (K @ self._p[:, :, None])[..., 0]
        self._K2p = (self._K2 @ self._p[:, :, None])[..., 0]
        self._eye = np.eye(3)
        self._axis_point = np.zeros((model.dof, 4, 2))  # homogeneous axis (w, 0), point (p, 1)
        self._axis_point[:, :3, 0], self._axis_point[:, :3, 1] = self._w, self._p
        self._axis_point[:, 3, 1] = 1.0
        self._tool_h = np.append((np.asarray(model.home) @ np.asarray(model.tool))[:3, 3], 1.0)
        self._base = np.asarray(model.base, dtype=float)
        self._base_is_identity = bool(np.allclose(self._base, np.eye(4), rtol=0, atol=0))

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if not self.fast:
            J, T = jacobian_and_pose(self.model, q)
            return T[:, :3, 3], J[:, :3]
        P, n = q.shape
        th = q + self._offset
        s, c = np.sin(th)[..., None], np.cos(th)[..., None]
        # Joint i: rotation R_i about its axis through p_i, i.e. [R_i, (I - R_i) p_i] with
        # R_i = I + s K + (1 - c) K^2 (Rodrigues), so (I - R_i) p_i = -s K p - (1 - c) K^2 p.
        T = np.zeros((P, n, 4, 4))
        T[..., :3, :3] = self._eye + s[..., None] * self._K + (1.0 - c[..., None]) * self._K2
        T[..., :3, 3] = -s * self._Kp - (1.0 - c) * self._K2p
        T[..., 3, 3] = 1.0
        d = 1
        while d < n:  # Hillis-Steele scan: T[:, i] becomes T_1 ... T_i
            T[:, d:] = T[:, :-d] @ T[:, d:]
            d *= 2
        # Joint i's own motion fixes its axis and point, so T_1 ... T_i maps them to the world
        # as T_1 ... T_(i-1) does: one product gives every axis (column 0) and point (1).
        ap = T[..., :3, :] @ self._axis_point  # (P, n, 3, 2)
        a, r = ap[..., 0], (T[:, -1, :3, :] @ self._tool_h)[:, None, :] - ap[..., 1]
        J = np.empty((P, 3, n))  # columns a x (p_tool - p_i)
        J[:, 0] = a[..., 1] * r[..., 2] - a[..., 2] * r[..., 1]
        J[:, 1] = a[..., 2] * r[..., 0] - a[..., 0] * r[..., 2]
        J[:, 2] = a[..., 0] * r[..., 1] - a[..., 1] * r[..., 0]
        p_tool = r[:, 0] + ap[:, 0, :, 1]
        if self._base_is_identity:
            return p_tool, J
        Rb, tb = self._base[:3, :3], self._base[:3, 3]
        return p_tool @ Rb.T + tb, Rb @ J


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
