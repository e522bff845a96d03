"""Batched forward kinematics for every convention of ``RobotModel``: tool poses
``T_world_tool = base · chain(q) · tool`` and every link frame, in the world frame (frames,
units and layouts: docs/conventions.md)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .fast import FK_BLOCK, chain_of, fk_rows, kernels
from .model import RobotModel
from .transforms import rot_x, trans

__all__ = ["as_batch", "batch_of", "fk", "fk_frames", "joint_axes"]


def batch_of(model: RobotModel, q) -> tuple[np.ndarray, tuple[int, ...]]:
    """Normalise ``q (*, dof)`` to ``(N, dof)`` float64 rows, with the leading shape ``*``
    (``()`` for a single ``(dof,)``) that the results are reshaped back to."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != model.dof:
        raise ValueError(
            f"q must have shape (..., {model.dof}) (e.g. (N, {model.dof}) or ({model.dof},)) "
            f"for robot '{model.id}', got {list(q.shape)}"
        )
    return q.reshape(-1, model.dof), q.shape[:-1]


def as_batch(model: RobotModel, q) -> tuple[np.ndarray, bool]:
    """Normalise ``q`` to ``(N, dof)`` float64; also says whether a single ``(dof,)`` was given.

    Only ``(N, dof)`` and ``(dof,)`` are accepted; ``batch_of`` takes any leading shape."""
    q = np.asarray(q, dtype=float)
    if q.ndim > 2:
        raise ValueError(
            f"q must have shape (N, {model.dof}) or ({model.dof},) for robot "
            f"'{model.id}', got {list(q.shape)}"
        )
    q2, lead = batch_of(model, q)
    return q2, lead == ()


def _right_multiply(T: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``T (N, 4, 4) @ A (4, 4)`` as one matrix product over all rows (one BLAS call)."""
    return (T.reshape(-1, 4) @ A).reshape(T.shape)


# The D-H chain is carried as four contiguous (3, N) arrays, the columns X, Y, Z, P of the
# running pose, rather than as (N, 4, 4) matrices: a joint's motion then costs a few
# contiguous vector operations instead of a batched 4x4 product.
Columns = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _mix(cols: Columns, coeffs: np.ndarray, extra: np.ndarray | None = None) -> np.ndarray:
    """``sum_k coeffs[k] * cols[k] (+ extra)``, skipping zero coefficients."""
    out = extra
    for k in range(3):
        a = coeffs[k]
        if a == 0.0:
            continue
        term = cols[k] if a == 1.0 else a * cols[k]
        out = term if out is None else out + term
    return np.zeros_like(cols[0]) if out is None else out


def _times_constant(cols: Columns, A: np.ndarray) -> Columns:
    """Columns of ``T @ A`` for a constant rigid ``A (4, 4)``."""
    return (
        _mix(cols, A[:3, 0]),
        _mix(cols, A[:3, 1]),
        _mix(cols, A[:3, 2]),
        _mix(cols, A[:3, 3], cols[3]),
    )


def cos_sin(theta) -> tuple[np.ndarray, np.ndarray]:
    """cos and sin of an array by the tangent half-angle: one vectorised ``tan`` instead of
    ``cos`` and ``sin`` (numpy's float64 ``tan`` has a SIMD kernel where ``cos``/``sin`` may
    not). Accurate to a few ulp over the whole circle, including at theta = pi."""
    t = np.tan(0.5 * np.asarray(theta, dtype=float))
    t2 = t * t
    inv = 1.0 / (1.0 + t2)
    return (1.0 - t2) * inv, 2.0 * t * inv


def _turn_and_slide(cols: Columns, theta, d) -> Columns:
    """Columns of ``T @ RotZ(theta) @ TransZ(d)``; theta, d scalars or ``(N,)``."""
    X, Y, Z, P = cols
    c, s = cos_sin(theta) if np.ndim(theta) else (np.cos(theta), np.sin(theta))
    return c * X + s * Y, c * Y - s * X, Z, P + d * Z


def _columns_to_poses(cols: Columns, n: int) -> np.ndarray:
    """``(N, 4, 4)`` poses, a view into one ``(4, 4, N)`` buffer filled row-block by row-block
    (contiguous writes; the transposed view costs nothing)."""
    buf = np.zeros((4, 4, n))
    for k in range(4):
        buf[:3, k, :] = cols[k]
    buf[3, 3, :] = 1.0
    return buf.transpose(2, 0, 1)


@lru_cache(maxsize=256)
def _link_constants(model: RobotModel) -> tuple[np.ndarray | None, ...]:
    """Per joint, the constant part of its D-H transform (None when it is the identity):
    ``RotX(alpha) TransX(a)`` (modified) or ``TransX(a) RotX(alpha)`` (standard)."""
    out = []
    for j in model.joints:
        if j.alpha == 0.0 and j.a == 0.0:
            out.append(None)
            continue
        A = rot_x(j.alpha) @ trans(j.a) if model.convention == "mdh" else trans(j.a) @ rot_x(
            j.alpha
        )
        # cos(pi/2) is 6e-17, not 0: snap such round-off so the column mixing can skip the
        # term (a change far below the precision of any length here).
        for v in (0.0, 1.0, -1.0):
            A[np.abs(A - v) < 1e-15] = v
        out.append(A)
    return tuple(out)


def _dh_columns(model: RobotModel, q: np.ndarray, keep: bool) -> tuple[Columns, list[Columns]]:
    """Modified D-H: ``RotX(alpha) TransX(a)`` then ``RotZ(theta) TransZ(d)``; standard D-H:
    the joint's ``RotZ(theta) TransZ(d)`` then ``TransX(a) RotX(alpha)``."""
    # Base columns as (3, 1): they broadcast to (3, N) at the first joint that moves.
    cols: Columns = tuple(model.base[:3, k, None].copy() for k in range(4))
    frames = [cols] if keep else []
    mdh = model.convention == "mdh"
    for i, (j, const) in enumerate(zip(model.joints, _link_constants(model))):
        fixed = const is None
        if mdh and not fixed:
            cols = _times_constant(cols, const)
        if j.revolute:
            cols = _turn_and_slide(cols, q[:, i] + j.offset, j.d)
        else:
            cols = _turn_and_slide(cols, j.theta, q[:, i] + j.offset)
        if not mdh and not fixed:
            cols = _times_constant(cols, const)
        if keep:
            frames.append(cols)
    return cols, frames


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
    if model.convention != "poe":
        cols, frames = _dh_columns(model, q, keep)
        n = q.shape[0]
        return _columns_to_poses(cols, n), [_columns_to_poses(c, n) for c in frames]
    links = _poe_links(model, q)
    T = np.broadcast_to(model.base, (q.shape[0], 4, 4))
    frames = [T] if keep else []
    for L in links:
        T = T @ L
        if keep:
            frames.append(T)
    return T, frames


def fk(model: RobotModel, q) -> np.ndarray:
    """Tool poses ``T_world_tool = base · chain(q) · tool`` in mm (docs/conventions.md).

    ``q: (*, dof) -> (*, 4, 4)``: any leading batch shape, e.g. ``(dof,) -> (4, 4)`` or
    ``(N, dof) -> (N, 4, 4)``. Runs on the compiled kernels when they are available
    (``kinematics.fast``), else on numpy, in blocks of ``FK_BLOCK`` configurations.
    """
    K = kernels()
    if K is not None and type(q) is np.ndarray and q.shape == (model.dof,) and \
            q.dtype == np.float64 and q.flags.c_contiguous and q.flags.writeable:
        # One configuration as the kernel takes it: no normalisation to pay for.
        ch = chain_of(model)
        T = np.empty((4, 4))
        K.fk_pose(ch.C, ch.prismatic, ch.offset, q, T)
        return T
    q2, lead = batch_of(model, q)
    if K is not None:
        return fk_rows(K, model, q2).reshape(lead + (4, 4))
    n = q2.shape[0]
    if n <= FK_BLOCK:
        return _fk_numpy(model, q2).reshape(lead + (4, 4))
    # Blocks small enough for the intermediate arrays to stay in cache: the time per
    # configuration stays flat with the batch size, and the memory bounded.
    T = np.empty((n, 4, 4))
    for start in range(0, n, FK_BLOCK):
        T[start:start + FK_BLOCK] = _fk_numpy(model, q2[start:start + FK_BLOCK])
    return T.reshape(lead + (4, 4))


def _fk_numpy(model: RobotModel, q2: np.ndarray) -> np.ndarray:
    """``fk`` of ``q2 (N, dof)`` by the batched numpy code (no compiled kernels)."""
    if model.convention == "poe":
        T, _ = _chain(model, q2, keep=False)
        return _right_multiply(T, model.home @ model.tool)
    cols, _ = _dh_columns(model, q2, keep=False)
    return _columns_to_poses(_times_constant(cols, model.tool), q2.shape[0])


def fk_frames(model: RobotModel, q) -> np.ndarray:
    """Every link frame in the world frame. ``q: (*, dof) -> (*, dof + 1, 4, 4)``.

    Entry 0 is the base frame (``T_world_base``, the model's ``base``), entry i the frame
    after joint i; the last entry is the tool pose ``T_world_tool`` (tool transform applied,
    equal to ``fk``). For product-of-exponentials models the intermediate frames are placed
    at each joint's axis point with the base orientation at q = 0, carried by the motion of
    the joints before and including it.
    """
    q2, lead = batch_of(model, q)
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
    return out.reshape(lead + (model.dof + 1, 4, 4))


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
    last, frames = _dh_columns(model, q2, keep=True)
    # MDH: joint i moves about z of frame i; SDH: about z of frame i-1.
    src = frames[1:] if model.convention == "mdh" else frames[:-1]
    axes = np.empty((n, model.dof, 3))
    points = np.empty((n, model.dof, 3))
    for i, (_, _, Z, P) in enumerate(src):
        axes[:, i] = Z.T
        points[:, i] = P.T
    return axes, points, _columns_to_poses(_times_constant(last, model.tool), n)
