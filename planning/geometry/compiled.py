"""A scene's objects as the flat arrays of the compiled kernels (``planning.geometry.kernels``),
through the shape registry: each object's code, world-to-local frame and parameters (its
shape's ``kernel_params``), bounds, and the ball sets of meshes and point clouds laid out on
their grids (``planning.geometry.balls.ball_grid``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .balls import BallSet, ball_grid
from .registry import KERNEL_CODES
from .table import shape_kind

__all__ = ["kernel_objects", "inverse_pose"]


def inverse_pose(T: np.ndarray) -> np.ndarray:
    """``T^-1`` of a rigid pose ``T (4, 4)``, its first three rows ``(3, 4)``."""
    R, p = T[:3, :3], T[:3, 3]
    out = np.empty((3, 4))
    out[:, :3] = R.T
    out[:, 3] = -R.T @ p
    return out


def kernel_objects(objects: Sequence, sets: Sequence[tuple[int, BallSet]],
                   bounds: Sequence[tuple[np.ndarray, np.ndarray]]) -> tuple | None:
    """``(kind (n,), T_inv (n, 3, 4), par (n, 4), aabb (n, 6), balls (N, 4), cells,
    set_meta (S, 9))`` of ``objects`` (``SceneObject``s) whose ball sets are ``sets``
    (``(object index, BallSet)``) and world bounds ``bounds``; None when some object's
    shape has no compiled kernel."""
    n = len(objects)
    kind = np.full(n, -1, dtype=np.int64)
    T_inv = np.zeros((n, 3, 4))
    par = np.zeros((n, 4))
    in_sets = {i for i, _ in sets}
    for i, o in enumerate(objects):
        if i in in_sets:
            continue
        shape = shape_kind(o.type)
        if shape.code is None:
            return None
        T, p = shape.kernel_params(o)
        kind[i], T_inv[i], par[i] = shape.code, inverse_pose(T), p
    balls, cells, meta = [], [np.zeros(1, np.int64)], []
    n_cells = 0
    for s, (i, bs) in enumerate(sets):
        kind[i], par[i, 0] = KERNEL_CODES["balls"], s
        B, start, m = ball_grid(bs.balls, n_cells)
        balls.append(B)
        cells.append(start[1:] + sum(len(x) for x in balls[:-1]))
        meta.append(m)
        n_cells += len(start) - 1
    aabb = np.array([np.r_[a, b] for a, b in bounds]).reshape(-1, 6)
    c = np.ascontiguousarray
    return (kind, c(T_inv), c(par), c(aabb),
            c(np.concatenate(balls)) if balls else np.zeros((0, 4)),
            c(np.concatenate(cells)).astype(np.int64), c(np.array(meta)).reshape(-1, 9))
