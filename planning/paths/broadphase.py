"""The broad phase of segment–obstacle checks: which obstacles can come within a distance
of a segment, found from bounding spheres before any exact distance is computed.

Each obstacle is given by a bounding sphere (centre, radius). A segment ``P0–P1`` lies in
the ball of radius ``h = |P1 - P0| / 2`` around its midpoint, so an obstacle whose bounding
sphere comes within ``reach`` of the segment has its centre within ``h + R + reach`` of the
midpoint. Segments are grouped by half-length and obstacles by radius (each group spans a
factor of two), a KD-tree per group pair returns every (segment, obstacle) pair within that
distance in one vectorised call (``scipy.spatial.cKDTree.sparse_distance_matrix``), and a
fine test keeps the pairs whose centre lies within ``R + reach`` of the segment itself.

The pairs returned are a superset of the pairs whose exact clearance is at most ``reach``:
the exact distance to a convex obstacle is never less than the distance to its bounding
sphere. Lengths in mm; segments ``P0, P1: (M, 3)``.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.segments import segment_point_distance

__all__ = ["BroadPhase", "MAX_PAIRS"]

#: Most candidate pairs one query returns; callers pass at most ``MAX_PAIRS // n`` segments
#: at a time with ``n`` obstacles, so a query's memory is bounded whatever the segments.
MAX_PAIRS = 1 << 20


def _groups(values: np.ndarray) -> list[np.ndarray]:
    """Indices of ``values (n,) >= 0`` grouped so that each group's largest value is at most
    twice its smallest (zeros together), largest first."""
    out = []
    zero = values <= 0
    if zero.any():
        out.append(np.nonzero(zero)[0])
    pos = np.nonzero(~zero)[0]
    if len(pos):
        level = np.floor(np.log2(values[pos] / values[pos].min())).astype(int)
        for lv in np.unique(level)[::-1]:
            out.append(pos[level == lv])
    return out


class BroadPhase:
    """Bounding spheres ``centres (n, 3)``, ``radii (n,)`` of ``n`` obstacles, and
    optionally their axis-aligned bounding boxes ``lower, upper (n, 3)`` (tighter for long
    or flat obstacles), indexed for segment queries."""

    def __init__(self, centres, radii, lower=None, upper=None) -> None:
        self.centres = np.asarray(centres, dtype=float).reshape(-1, 3)
        self.radii = np.asarray(radii, dtype=float).reshape(-1)
        if lower is None or upper is None:
            lower, upper = self.centres - self.radii[:, None], self.centres + self.radii[:, None]
        self.lower = np.asarray(lower, dtype=float).reshape(-1, 3)
        self.upper = np.asarray(upper, dtype=float).reshape(-1, 3)
        self._groups = [(idx, cKDTree(self.centres[idx]), float(self.radii[idx].max()))
                        for idx in _groups(self.radii)]
        #: Longest piece a segment is queried in: four median bounding radii.
        self.piece = 4.0 * float(np.median(self.radii)) if len(self.radii) else 1.0
        if not self.piece > 0:
            self.piece = 1.0

    def __len__(self) -> int:
        return len(self.radii)

    def pairs(self, P0, P1, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """Candidate pairs ``(segment (k,), obstacle (k,))`` in no particular order: every
        obstacle whose bounding sphere comes within ``reach`` (mm, may be negative) of
        segment ``P0[i]–P1[i]``. A pair may come more than once (a segment queried in pieces
        meets an obstacle from two of them), at most once per piece.

        Segments longer than ``piece`` are queried as pieces of at most that length, so a
        long segment meets the obstacles along it, not every one within half its length of
        its midpoint."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        length = np.linalg.norm(P1 - P0, axis=1)
        cuts = np.maximum(1, np.ceil(length / self.piece)).astype(np.int64)
        found_seg, found_obs = [], []
        # Pieces in batches of at most MAX_PAIRS, whole segments each.
        ends = np.cumsum(cuts)
        first = ends - cuts  # index of each segment's first piece
        a = 0
        while a < len(P0):
            b = max(a + 1, int(np.searchsorted(ends, first[a] + MAX_PAIRS, "right")))
            owner = np.repeat(np.arange(a, b), cuts[a:b])
            k = np.arange(first[a], ends[b - 1]) - first[owner]
            m = cuts[owner].astype(float)
            d = P1[owner] - P0[owner]
            mid = P0[owner] + ((k + 0.5) / m)[:, None] * d
            half = 0.5 * length[owner] / m
            seg, ob = self._ball_pairs(mid, half, reach)
            if len(seg):
                found_seg.append(owner[seg])
                found_obs.append(ob)
            if sum(len(x) for x in found_seg) > MAX_PAIRS:  # repeats would pile up: drop them
                key = np.unique(np.concatenate(found_seg) * len(self) + np.concatenate(found_obs))
                found_seg, found_obs = [key // len(self)], [key % len(self)]
            a = b
        if not found_seg:
            return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp)
        seg, ob = np.concatenate(found_seg), np.concatenate(found_obs)
        # Fine test: the centre's distance to the segment itself, not to a piece's ball.
        keep = self.lower_bounds(P0, P1, seg, ob) <= reach
        return seg[keep], ob[keep]

    def _ball_pairs(self, mid: np.ndarray, half: np.ndarray, reach: float
                    ) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (ball, obstacle) whose centres lie within ``half + R + reach``, where the
        balls have centres ``mid (m, 3)`` and radii ``half (m,)``."""
        segs, obs = [], []
        for s_idx in _groups(half):
            s_tree = cKDTree(mid[s_idx])
            h_max = float(half[s_idx].max())
            for o_idx, o_tree, r_max in self._groups:
                bound = h_max + r_max + reach
                if bound < 0:
                    continue
                bound += 1e-9 * (bound + h_max + r_max) + 1e-12  # rounding of the tree's norm
                # Counted first, so that one call returns at most MAX_PAIRS pairs.
                count = o_tree.query_ball_point(mid[s_idx], bound, return_length=True)
                if count.sum() <= MAX_PAIRS:
                    parts = [np.arange(len(s_idx))]
                else:
                    ends = np.cumsum(count)
                    cut = np.searchsorted(ends, np.arange(MAX_PAIRS, int(ends[-1]), MAX_PAIRS))
                    parts = np.split(np.arange(len(s_idx)), np.unique(cut))
                for part in parts:
                    if not len(part):
                        continue
                    tree = s_tree if len(part) == len(s_idx) else cKDTree(mid[s_idx[part]])
                    found = tree.sparse_distance_matrix(o_tree, bound, output_type="ndarray")
                    if len(found):
                        segs.append(s_idx[part[found["i"]]])
                        obs.append(o_idx[found["j"]])
        if not segs:
            return np.empty(0, dtype=np.intp), np.empty(0, dtype=np.intp)
        return np.concatenate(segs), np.concatenate(obs)

    def chunk(self) -> int:
        """Segments per query that keep a query within ``MAX_PAIRS`` pairs at worst."""
        return max(1, MAX_PAIRS // max(1, len(self)))

    def lower_bounds(self, P0, P1, seg: np.ndarray, obs: np.ndarray) -> np.ndarray:
        """A lower bound ``(k,)`` of the clearance between segment ``seg[k]`` and obstacle
        ``obs[k]``: the larger of the distance to its bounding sphere (negative inside) and
        the gap between the segment's and the obstacle's bounding boxes along the axis that
        separates them most (0 or less when they overlap)."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        a, b, c = P0[seg], P1[seg], self.centres[obs]
        ball = segment_point_distance(a, b, c)[0] - self.radii[obs]
        gap = np.max(np.maximum(self.lower[obs] - np.maximum(a, b),
                                np.minimum(a, b) - self.upper[obs]), axis=1)
        return np.maximum(ball, gap)



class BlockedGrid:
    """Cells of a grid every point of which is closer than ``margin`` to an obstacle: a
    segment with a point in one cannot be clear by ``margin``, so most segments through
    obstacles are rejected by a table look-up before any exact check.

    The grid has cubic cells of edge ``cell`` (mm) in the frame ``origin (3,)``, ``axes
    (3, 3)`` (rows: orthonormal axes), covering ``shape`` cells from the origin. A cell is
    blocked when its centre's exact clearance is below ``margin - cell * sqrt(3) / 2``: the
    clearance changes by at most 1 mm per mm, so every point of the cell is then closer than
    ``margin``. Obstacles whose cells would pass the build budget are left out, which only
    blocks fewer cells.
    """

    #: Most (cell, obstacle) clearances computed to build one grid.
    BUILD_PAIRS = 1 << 20
    #: Most points of one segment looked up.
    MAX_LOOKUPS = 64

    def __init__(self, scene, origin, axes, extent, margin: float, max_cells: int) -> None:
        self.origin = np.asarray(origin, dtype=float)
        self.axes = np.asarray(axes, dtype=float)
        extent = np.maximum(np.asarray(extent, dtype=float), 1e-9)
        centres, radii = scene.bounding_spheres()
        lower, upper = scene.bounding_boxes()
        grow = max(margin, 0.0)
        # Each obstacle's bounding box in grid coordinates: its corners' extent (a box
        # turned into the frame), or its bounding sphere's when that is smaller.
        corner = np.stack([np.where(np.array(bits, dtype=bool), upper, lower)
                           for bits in np.ndindex(2, 2, 2)], axis=1)  # (n, 8, 3)
        local = (corner - np.asarray(origin, dtype=float)) @ self.axes.T
        c_local = (centres - np.asarray(origin, dtype=float)) @ self.axes.T
        box_lo = np.maximum(local.min(axis=1), c_local - radii[:, None]) - grow
        box_hi = np.minimum(local.max(axis=1), c_local + radii[:, None]) + grow
        # Cells no smaller than the grid's cap allows, nor than what lets the obstacles'
        # cells fit in the build budget.
        volume = float(np.sum(np.prod(box_hi - box_lo, axis=1)))
        self.cell = float(max(np.cbrt(np.prod(extent) / max(1, max_cells)),
                              np.cbrt(volume / self.BUILD_PAIRS),
                              float(extent.max()) / 4096.0))
        self.shape = tuple(int(v) for v in np.maximum(1, np.ceil(extent / self.cell)))
        self.blocked = np.zeros(self.shape, dtype=bool)
        self._padded: np.ndarray | None = None
        if not len(radii):
            return
        dims = np.array(self.shape)
        lo = np.clip(np.floor(box_lo / self.cell).astype(np.int64), 0, dims)
        hi = np.clip(np.ceil(box_hi / self.cell).astype(np.int64), 0, dims)
        size = np.maximum(hi - lo, 0)
        count = np.prod(size, axis=1)
        order = np.argsort(count, kind="stable")
        take = order[np.cumsum(count[order]) <= self.BUILD_PAIRS]
        take = take[count[take] > 0]
        threshold = margin - self.cell * np.sqrt(3.0) / 2.0
        ends = np.cumsum(count[take])
        first = ends - count[take]
        a = 0
        while a < len(take):
            b = max(a + 1, int(np.searchsorted(ends, first[a] + MAX_PAIRS, "right")))
            j = np.repeat(np.arange(a, b), count[take[a:b]])
            k = np.arange(first[a], ends[b - 1]) - first[j]
            ob = take[j]
            sy, sz = size[ob, 1], size[ob, 2]
            ijk = lo[ob] + np.stack([k // (sy * sz), (k // sz) % sy, k % sz], axis=1)
            X = self.origin + ((ijk + 0.5) * self.cell) @ self.axes
            inside = scene.pair_clearance(X, X, ob) < threshold
            ijk = ijk[inside]
            self.blocked[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = True
            a = b

    def hits(self, P0, P1) -> np.ndarray:
        """``(M,)`` bool: a point of segment ``P0[i]–P1[i]`` (about one per cell length
        along it, at most ``MAX_LOOKUPS``) lies in a blocked cell. False says nothing.

        Points are looked up coarse to fine (the midpoint, then the quarter points, ...),
        each level only for the segments not hit yet: a segment through an obstacle is
        usually rejected after a look-up or two."""
        P0 = np.asarray(P0, dtype=float).reshape(-1, 3)
        P1 = np.asarray(P1, dtype=float).reshape(-1, 3)
        out = np.zeros(len(P0), dtype=bool)
        if not self.blocked.any() or not len(P0):
            return out
        # Grid coordinates shifted by one cell into a grid padded with free cells: a point
        # outside lands, after clipping, in the padding.
        a0 = (P0 - self.origin) @ self.axes.T / self.cell + 1.0
        d = (P1 - self.origin) @ self.axes.T / self.cell + 1.0 - a0
        need = np.clip(np.ceil(np.linalg.norm(d, axis=1)), 1, self.MAX_LOOKUPS)
        if self._padded is None:
            self._padded = np.pad(self.blocked, 1).ravel()
        padded = self._padded
        top = np.array(self.shape) + 1
        stride = np.array([(self.shape[1] + 2) * (self.shape[2] + 2), self.shape[2] + 2, 1])
        alive = np.arange(len(P0))
        points = 1
        while len(alive):
            # Level with ``points`` new points per segment: t = (2k + 1) / (2 points).
            t = (2 * np.arange(points) + 1) / (2.0 * points)
            step = max(1, MAX_PAIRS // points)
            for s in range(0, len(alive), step):
                seg = alive[s:s + step]
                g = (a0[seg, None, :] + t[None, :, None] * d[seg, None, :]).astype(np.int64)
                np.clip(g, 0, top, out=g)  # (truncation = floor here: coordinates >= 0)
                hit = padded[g @ stride].reshape(len(seg), points).any(axis=1)
                out[seg[hit]] = True
            alive = alive[~out[alive] & (need[alive] > points)]
            points *= 2
        return out
