"""Ball sets: the sphere stage's stand-in for meshes and point clouds (the union of the balls
contains the shape, ``planning.geometry.spheres``), with exact distances to them.

``BallSet.distance`` answers through a k-d tree (the nearest balls, widened until the answer
is certain); ``ball_grid`` lays a set out on a grid of cells for the compiled kernels
(``planning.geometry.kernels``), which visit only the cells near a point. Lengths in mm;
balls are rows ``[x, y, z, radius]``.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["BallSet", "ball_grid", "SET_CELLS"]

#: Nearest balls of a ball set looked at first (widened until certain).
_KNN = 8
#: Largest number of cells of one ball set's grid.
SET_CELLS = 1 << 18


class BallSet:
    """Balls ``(M, 4)`` of one mesh or point cloud, with exact distances to them."""

    def __init__(self, balls: np.ndarray) -> None:
        from scipy.spatial import cKDTree

        self.balls = balls
        self.tree = cKDTree(balls[:, :3])
        self.rmax = float(balls[:, 3].max())

    def distance(self, P: np.ndarray, cap: float = math.inf) -> np.ndarray:
        """Signed distance ``(K,)`` of points to the union of the balls: the nearest
        centres, widened until no farther ball can be nearer. With ``cap``, a distance
        above it may be answered as ``cap`` (only centres within ``cap + rmax`` are looked
        at: what the distance grid, capped itself, needs)."""
        n = len(self.balls)
        k = min(_KNN, n)
        out = np.empty(len(P))
        todo = np.arange(len(P))
        bound = cap + self.rmax
        while len(todo):
            d, i = self.tree.query(P[todo], k=k, distance_upper_bound=bound)
            d, i = d.reshape(len(todo), k), i.reshape(len(todo), k)
            found = np.isfinite(d)
            r = self.balls[np.where(found, i, 0), 3]
            best = np.where(found, d - r, np.inf).min(axis=1)
            best = np.minimum(best, cap)
            last = np.where(found[:, -1], d[:, -1], bound)
            sure = (k >= n) | ~found[:, -1] | (last - self.rmax >= best)
            out[todo[sure]] = best[sure]
            todo = todo[~sure]
            k = min(4 * k, n)
        return out

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World axis-aligned bounds ``(lower (3,), upper (3,))`` of the balls."""
        b = self.balls
        return (b[:, :3] - b[:, 3:]).min(0), (b[:, :3] + b[:, 3:]).max(0)


def ball_grid(balls: np.ndarray, first: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Balls sorted by the cell of their centre on a grid over them, the cells' starts
    ``(cells + 1,)`` (from 0) and the set's meta row (lo, h, shape, first cell, rmax), as
    the compiled kernels read them."""
    lo = balls[:, :3].min(0)
    hi = balls[:, :3].max(0)
    ext = np.maximum(hi - lo, 1e-9)
    r = float(np.median(balls[:, 3]))
    h = max(4.0 * r, float(np.cbrt(ext.prod() / SET_CELLS)), 1e-6)
    shape = np.maximum(np.floor(ext / h).astype(np.int64) + 1, 1)
    while shape.prod() > SET_CELLS:
        h *= 1.1
        shape = np.maximum(np.floor(ext / h).astype(np.int64) + 1, 1)
    idx = np.minimum(np.floor((balls[:, :3] - lo) / h).astype(np.int64), shape - 1)
    flat = (idx[:, 0] * shape[1] + idx[:, 1]) * shape[2] + idx[:, 2]
    order = np.argsort(flat, kind="stable")
    counts = np.bincount(flat, minlength=int(shape.prod()))
    start = np.r_[0, np.cumsum(counts)].astype(np.int64)
    meta = np.r_[lo, h, shape, first, balls[:, 3].max()].astype(float)
    return balls[order], start, meta
