"""Batched forward kinematics for every convention of ``RobotModel``."""

from __future__ import annotations

import numpy as np

from .model import RobotModel

__all__ = ["as_batch", "fk", "fk_frames", "joint_axes"]


def as_batch(model: RobotModel, q) -> tuple[np.ndarray, bool]:
    """Normalise ``q`` to ``(N, dof)`` float64; also says whether a single ``(dof,)`` was given."""
    q = np.asarray(q, dtype=float)
    single = q.ndim == 1
    q2 = q[None, :] if single else q
    if q2.ndim != 2 or q2.shape[1] != model.dof:
        raise ValueError(
            f"q must have shape (N, {model.dof}) or ({model.dof},) for robot "
            f"'{model.id}', got {list(q.shape)}"
        )
    return q2, single


def _dh_links(model: RobotModel, q: np.ndarray) -> list[np.ndarray]:
    """Link transforms ``T_{i-1,i}`` as a list of ``(N, 4, 4)``, one per joint."""
    n = q.shape[0]
    links = []
    for i, j in enumerate(model.joints):
        if j.revolute:
            theta = q[:, i] + j.offset
            d = np.full(n, j.d)
        else:
            theta = np.full(n, j.theta)
            d = q[:, i] + j.offset
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = np.cos(j.alpha), np.sin(j.alpha)
        T = np.zeros((n, 4, 4))
        if model.convention == "mdh":
            # RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
            T[:, 0, 0], T[:, 0, 1], T[:, 0, 3] = ct, -st, j.a
            T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 1, 3] = st * ca, ct * ca, -sa, -sa * d
            T[:, 2, 0], T[:, 2, 1], T[:, 2, 2], T[:, 2, 3] = st * sa, ct * sa, ca, ca * d
        else:
            # RotZ(theta) TransZ(d) TransX(a) RotX(alpha)
            T[:, 0, 0], T[:, 0, 1], T[:, 0, 2], T[:, 0, 3] = ct, -st * ca, st * sa, j.a * ct
            T[:, 1, 0], T[:, 1, 1], T[:, 1, 2], T[:, 1, 3] = st, ct * ca, -ct * sa, j.a * st
            T[:, 2, 1], T[:, 2, 2], T[:, 2, 3] = sa, ca, d
        T[:, 3, 3] = 1.0
        links.append(T)
    return links


def _screw_exp(axis: np.ndarray, point: np.ndarray | None, x: np.ndarray) -> np.ndarray:
    """exp of a unit screw for joint values ``x: (N,)`` -> ``(N, 4, 4)``.

    Revolute about ``axis`` through ``point``; prismatic along ``axis`` when ``point`` is None.
    """
    n = x.shape[0]
    T = np.zeros((n, 4, 4))
    T[:, 3, 3] = 1.0
    if point is None:
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = 1.0
        T[:, :3, 3] = x[:, None] * axis
        return T
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    s, c = np.sin(x)[:, None, None], np.cos(x)[:, None, None]
    R = np.eye(3) + s * K + (1 - c) * (K @ K)
    T[:, :3, :3] = R
    # Rotation about a line through `point`: p' = R (p - point) + point.
    T[:, :3, 3] = point - R @ point
    return T


def _poe_links(model: RobotModel, q: np.ndarray) -> list[np.ndarray]:
    links = []
    for i, j in enumerate(model.joints):
        axis = np.asarray(j.axis)
        point = np.asarray(j.point) if j.revolute else None
        links.append(_screw_exp(axis, point, q[:, i] + j.offset))
    return links


def _chain(model: RobotModel, q: np.ndarray, keep: bool) -> tuple[np.ndarray, list[np.ndarray]]:
    links = _poe_links(model, q) if model.convention == "poe" else _dh_links(model, q)
    T = np.broadcast_to(model.base, (q.shape[0], 4, 4))
    frames = [T] if keep else []
    for L in links:
        T = T @ L
        if keep:
            frames.append(T)
    return T, frames


def fk(model: RobotModel, q) -> np.ndarray:
    """Tool poses. ``q: (N, dof) -> (N, 4, 4)``, or ``(dof,) -> (4, 4)``; base frame, mm."""
    q2, single = as_batch(model, q)
    T, _ = _chain(model, q2, keep=False)
    if model.home is not None:
        T = T @ model.home
    T = T @ model.tool
    return T[0] if single else T


def fk_frames(model: RobotModel, q) -> np.ndarray:
    """Every link frame. ``q: (N, dof) -> (N, dof + 1, 4, 4)`` (or ``(dof+1, 4, 4)``).

    Entry 0 is the base, entry i the frame after joint i; the last entry is the tool pose
    (tool transform applied). For product-of-exponentials models the intermediate frames are
    placed at each joint's axis point with the base orientation at q = 0, carried by the
    motion of the joints before and including it.
    """
    q2, single = as_batch(model, q)
    T, frames = _chain(model, q2, keep=True)
    if model.convention == "poe":
        for i, j in enumerate(model.joints[:-1]):
            M = np.eye(4)
            if j.point is not None:
                M[:3, 3] = j.point
            frames[i + 1] = frames[i + 1] @ M
        T = T @ model.home
    frames[-1] = T @ model.tool
    out = np.stack(frames, axis=1)
    return out[0] if single else out


def joint_axes(model: RobotModel, q2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-frame joint axes for ``q2: (N, dof)``.

    Returns ``(axes (N, dof, 3), points (N, dof, 3), T_tool (N, 4, 4))``: the unit direction
    of each joint's motion axis, a point on it, and the tool pose.
    """
    n = q2.shape[0]
    if model.convention == "poe":
        T, frames = _chain(model, q2, keep=True)
        axes = np.empty((n, model.dof, 3))
        points = np.empty((n, model.dof, 3))
        for i, j in enumerate(model.joints):
            Tp = frames[i]  # motion of the joints before joint i
            axes[:, i] = Tp[:, :3, :3] @ np.asarray(j.axis)
            p = np.asarray(j.point) if j.point is not None else np.zeros(3)
            points[:, i] = Tp[:, :3, :3] @ p + Tp[:, :3, 3]
        T_tool = T @ model.home @ model.tool
        return axes, points, T_tool
    T, frames = _chain(model, q2, keep=True)
    # MDH: joint i moves about z of frame i; SDH: about z of frame i-1.
    src = frames[1:] if model.convention == "mdh" else frames[:-1]
    F = np.stack(src, axis=1)
    return F[..., :3, 2], F[..., :3, 3], T @ model.tool
