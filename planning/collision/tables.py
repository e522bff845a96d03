"""Joint-space distance tables for link pairs that one or two joints apart.

Two links of a serial chain whose frames are one or two joints apart (Panda ``link5`` and
``link7``: joints 6 and 7) stay close in most configurations, and there the sphere stage's
slack makes most of its false alarms. Their relative pose depends on those joints only, so
their distance is a function of one or two variables: it is tabulated once on a grid over
the joint limits, and read back as a certified lower bound. The tabulated distance is FCL's
(GJK) between the convex hulls of the links' meshes (and their primitives): at most the
meshes' own distance, so still a lower bound, exact for convex links and seven times faster
to build than the triangle-level distance; where the hulls come within 25 mm, the meshes'
own distance (FCL on the triangles) replaces it, so that concave links that nest (UR5's
base and upper arm) are not held in contact by their hulls.

Bound: turning joint ``j`` by ``dq`` moves every point of the outer link by at most
``rho_j |dq|``, where ``rho_j`` is the largest distance of the outer link's geometry from a
point on the joint's axis (for the outer joint, the distance from its axis point to the link's
bounding ball, plus that ball's radius; for the inner joint, plus the distance between the two
axis points, which the outer joint does not change); a prismatic joint moves it by ``|dq|``.
The distance is therefore ``rho``-Lipschitz, and ``table[node] - sum_j rho_j |q_j - node_j|``
is a lower bound at ``q`` for every grid node: the largest over the surrounding nodes is
used. The grid is sized so that this slack is at most ``tolerance`` mm (within ``max_nodes``
nodes; coarser if it must). Lengths in mm, angles in rad.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["PairTable", "build_pair_table", "TABLE_TOLERANCE", "TABLE_MAX_NODES"]

#: Target slack (mm) of a table's lower bound, and most grid nodes of one table.
TABLE_TOLERANCE = 1.5
TABLE_MAX_NODES = 50_000


@dataclass(frozen=True, eq=False)
class PairTable:
    """Exact distance of model links ``a`` and ``b`` over chain joints ``joints (k,)``
    (0-based): ``values`` on the grid ``lo + step * i`` of ``shape``, and the Lipschitz
    factors ``rho (k,)`` (mm per rad, or 1 per mm)."""

    a: int
    b: int
    pair: int
    joints: np.ndarray
    lo: np.ndarray
    step: np.ndarray
    shape: tuple
    rho: np.ndarray
    values: np.ndarray

    def _index(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The grid's corner offsets, last indices and strides (computed once)."""
        cached = self.__dict__.get("_cached")
        if cached is None:
            shape = np.asarray(self.shape, dtype=np.intp)
            corners = np.array(list(itertools.product((0, 1), repeat=len(self.joints))),
                               dtype=np.intp)
            cached = (corners, shape - 1, np.cumprod(np.r_[shape[1:], 1][::-1])[::-1])
            object.__setattr__(self, "_cached", cached)
        return cached

    @property
    def slack(self) -> float:
        """The largest gap (mm) between a lookup and the true distance's lower bound."""
        return float((self.rho * self.step).sum() / 2)

    def lower_bound(self, q2: np.ndarray) -> np.ndarray:
        """A lower bound ``(B,)`` of the pair's distance at ``q2 (B, dof)``: the best over
        the grid nodes around each configuration."""
        corners, last, strides = self._index()
        x = q2[:, self.joints]
        base = np.clip(((x - self.lo) / self.step).astype(np.intp), 0, last)
        idx = np.minimum(base[:, None, :] + corners, last)   # (B, 2^k, k)
        gap = np.abs(x[:, None, :] - (self.lo + idx * self.step)) @ self.rho
        return (self.values[idx @ strides] - gap).max(axis=1)


def build_pair_table(robot: Any, link_a: int, link_b: int, ball_b: tuple,
                     shapes_a: list, shapes_b: list, tolerance: float = TABLE_TOLERANCE,
                     max_nodes: int = TABLE_MAX_NODES, a: int = 0, b: int = 0,
                     pair: int = 0, refine: float = 25.0,
                     exact_margin: float = 10.0) -> PairTable | None:
    """The table of robot links ``link_a`` (inner) and ``link_b`` (outer) (indices into
    ``robot.links``), or None when their frames are not one or two chain joints apart.
    ``ball_b = (centre (3,), radius)``: a ball containing link b's geometry in its frame;
    ``shapes_a``, ``shapes_b``: their exact shapes (``planning.collision.exact``); ``a``,
    ``b``: the links' indices in the collision model, ``pair`` the pair's. Nodes where the
    hulls come within ``refine`` mm get the meshes' own distance."""
    import fcl

    la, lb = robot.links[link_a], robot.links[link_b]
    if robot.model.convention != "poe" or getattr(la, "mimic", ()) or getattr(lb, "mimic", ()):
        return None
    k = lb.frame - la.frame
    if k not in (1, 2):
        return None
    model = robot.model
    joints = np.arange(la.frame, lb.frame)          # chain joints frame_a+1 .. frame_b
    mid = model.mid_configuration()
    # The distances that bound rho do not depend on the joints: take them at q = 0, where
    # the product-of-exponentials axis points are the model's own (base frame).
    T_b = robot.link_poses(np.zeros(model.dof))[link_b]
    centre = T_b[:3, :3] @ np.asarray(ball_b[0]) + T_b[:3, 3]

    def axis_point(j: int) -> np.ndarray:
        return model.base[:3, :3] @ np.asarray(model.joints[j].point) + model.base[:3, 3]

    rho = np.empty(k)
    revolute = [model.joints[j].revolute and model.joints[j].point is not None for j in joints]
    outer = float(np.linalg.norm(centre - axis_point(joints[-1])) + ball_b[1]) \
        if revolute[-1] else 0.0
    for i in range(k - 1, -1, -1):
        j = joints[i]
        if not revolute[i]:
            rho[i] = 1.0
        elif i == k - 1:
            rho[i] = outer
        elif revolute[k - 1]:
            rho[i] = float(np.linalg.norm(axis_point(joints[-1]) - axis_point(j))) + outer
        else:
            return None  # a prismatic joint outside a revolute one: no simple bound
    lo = np.asarray(model.lower)[joints].astype(float)
    span = np.asarray(model.upper)[joints] - lo
    step = np.maximum(2 * tolerance / (k * np.maximum(rho, 1e-9)), 1e-6)
    n = np.maximum(np.ceil(span / step).astype(int) + 1, 2)
    if n.prod() > max_nodes:
        n = np.maximum(np.floor(n * (max_nodes / n.prod()) ** (1 / k)).astype(int), 2)
    step = np.where(span > 0, span / (n - 1), 1.0)
    hull_a = [fcl.CollisionObject(_hull_geometry(s), _tf(s.T)) for s in shapes_a]
    hull_b = [(fcl.CollisionObject(_hull_geometry(s), _tf(s.T)), s.T) for s in shapes_b]
    mesh_a = [fcl.CollisionObject(s.geom, _tf(s.T)) for s in shapes_a]
    mesh_b = [(fcl.CollisionObject(s.geom, _tf(s.T)), s.T) for s in shapes_b]
    convex = all(s.kind != "mesh" for s in (*shapes_a, *shapes_b))

    def exact(idx: np.ndarray) -> np.ndarray:
        """FCL distances at grid nodes ``idx (N, k)``: the hulls', and the meshes' where
        the hulls come within ``refine`` mm (concave links that nest are not held in
        contact by their hulls)."""
        Q = np.repeat(mid[None], len(idx), axis=0)
        Q[:, joints] = lo + idx * step
        P = robot.link_poses(Q)
        rel = np.linalg.inv(P[:, link_a]) @ P[:, link_b]
        out = np.array([_distance(hull_a, hull_b, R) for R in rel])
        if not convex:
            for i in np.flatnonzero(out < refine):
                out[i] = _distance(mesh_a, mesh_b, rel[i])
        return out

    values = _adaptive_values(tuple(int(x) for x in n), rho * step,
                              float((rho * step).sum()) + exact_margin, exact)
    return PairTable(a, b, pair, joints, lo, step, tuple(int(x) for x in n), rho, values)


def _adaptive_values(shape: tuple, gap: np.ndarray, exact_below: float, exact) -> np.ndarray:
    """Lower bounds ``(prod(shape),)`` of the distance at every node of a grid of ``shape``,
    coarse to fine: the nodes of a level (index stride ``s``) that the coarser level (stride
    ``2 s``) bounds below ``exact_below`` mm get ``exact(idx)``; the others keep that bound
    (``value - sum_j gap_j |i_j - c_j|`` at the best surrounding coarser node ``c``; ``gap``
    mm per index step). Far from contact the table thus holds bounds, near it the distance.
    """
    shape_a = np.asarray(shape, dtype=np.intp)
    k = len(shape)
    top = 1
    while np.any((shape_a - 1) // (2 * top) >= 4):
        top *= 2
    values = np.full(shape, np.nan)

    def lattice(stride: int) -> list[np.ndarray]:
        return [np.unique(np.r_[np.arange(0, m, stride), m - 1]) for m in shape]

    def nodes(axes: list[np.ndarray]) -> np.ndarray:
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, k)

    coarse = lattice(top)
    idx = nodes(coarse)
    values[tuple(idx.T)] = exact(idx)
    corners = np.array(list(itertools.product((0, 1), repeat=k)), dtype=np.intp)
    stride = top
    while stride > 1:
        stride //= 2
        fine = lattice(stride)
        idx = nodes(fine)
        idx = idx[np.isnan(values[tuple(idx.T)])]
        if len(idx) == 0:
            continue
        # The coarser lattice's nodes around each new node, per axis.
        below = np.column_stack([coarse[j][np.clip(np.searchsorted(coarse[j], idx[:, j],
                                                                    side="right") - 1,
                                                    0, len(coarse[j]) - 1)]
                                 for j in range(k)])
        above = np.column_stack([coarse[j][np.clip(np.searchsorted(coarse[j], idx[:, j]),
                                                    0, len(coarse[j]) - 1)]
                                 for j in range(k)])
        bound = np.full(len(idx), -np.inf)
        touching = np.ones(len(idx), dtype=bool)
        for corner in corners:
            c = np.where(corner[None] == 1, above, below)
            around = values[tuple(c.T)]
            bound = np.maximum(bound, around - np.abs(idx - c) @ gap)
            touching &= around <= 0.0
        # Inside a cell whose corners all touch, the links touch too (or nearly): the bound
        # (at most 0) stands, and the exact stage decides there as it would on a table of
        # zeros. Links that touch everywhere (parts of one wrist) thus cost a table's coarse
        # levels, not every node.
        need = (bound < exact_below) & ~touching
        values[tuple(idx[~need].T)] = bound[~need]
        if need.any():
            values[tuple(idx[need].T)] = exact(idx[need])
        coarse = fine
    return values.ravel()


def _distance(objs_a: list, objs_b: list, R: np.ndarray) -> float:
    """Least FCL distance (0 when touching) between shapes of link a (in its frame) and of
    link b placed at ``R = T_a_b``."""
    import fcl

    best = math.inf
    request = fcl.DistanceRequest()
    for ob, T in objs_b:
        ob.setTransform(_tf(R @ T))
        for oa in objs_a:
            d = fcl.distance(oa, ob, request, fcl.DistanceResult())
            best = min(best, 0.0 if d < 0 else d)
    return best


def _hull_geometry(shape: Any):
    """FCL geometry of a shape's convex hull (the shape itself for a primitive)."""
    import fcl
    from scipy.spatial import ConvexHull

    if shape.kind != "mesh":
        return shape.geom
    V = shape.data["triangles"].reshape(-1, 3)
    hull = ConvexHull(V)
    keep = hull.vertices
    remap = np.full(len(V), -1)
    remap[keep] = np.arange(len(keep))
    faces = remap[hull.simplices]
    flat = np.column_stack([np.full(len(faces), 3), faces]).ravel()
    return fcl.Convex(np.ascontiguousarray(V[keep]), len(faces), flat)


def _tf(T: np.ndarray):
    import fcl

    return fcl.Transform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
