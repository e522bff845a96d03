"""Joint-space distance tables for link pairs one or two joints apart, or three or four
with links swept about the joints at the ends.

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
nodes; coarser if it must). The first joint's axis is fixed to the inner link, and
``d(a, R(q) b) = d(R(-q) a, b)``: its factor is also at most the inner link's farthest point
from that axis, and the smaller is used (a round base under an arm).

Links farther apart: a link nearly round about the joint at its end of the pair (a wrist
flange about the last joint) is replaced by its swept solid about that joint
(``swept_slabs``: a stack of discs containing the link at every angle), which makes the
distance a lower bound at every angle of that joint, so the joint leaves the table.
Lengths in mm, angles in rad.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["PairTable", "build_pair_table", "swept_slabs", "sweep_ratio", "TABLE_TOLERANCE",
           "TABLE_MAX_NODES"]

#: Target slack (mm) of a table's lower bound, and most grid nodes of one table.
TABLE_TOLERANCE = 1.5
TABLE_MAX_NODES = 50_000


@dataclass(frozen=True, eq=False)
class PairTable:
    """Exact distance of model links ``a`` and ``b`` over chain joints ``joints (k,)``
    (0-based): ``values`` on the grid ``lo + step * i`` of ``shape``, and the Lipschitz
    factors ``rho (k,)`` (mm per rad, or 1 per mm). ``sweep``: ``""``, or which of the
    links (``"a"``, ``"b"``, ``"ab"``) the table holds turned about its swept joint
    (``build_pair_table``); a pair may have several tables, each a lower bound."""

    a: int
    b: int
    pair: int
    joints: np.ndarray
    lo: np.ndarray
    step: np.ndarray
    shape: tuple
    rho: np.ndarray
    values: np.ndarray
    sweep: str = ""

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
                     exact_margin: float = 10.0, sweep: tuple = (False, False),
                     triangles_a: np.ndarray | None = None,
                     triangles_b: np.ndarray | None = None) -> PairTable | None:
    """The table of robot links ``link_a`` (inner) and ``link_b`` (outer) (indices into
    ``robot.links``), or None when it cannot be built: the frames are not one or two
    tabulated chain joints apart, or a swept joint is not revolute.
    ``ball_b = (centre (3,), radius)``: a ball containing link b's geometry in its frame;
    ``shapes_a``, ``shapes_b``: their exact shapes (``planning.collision.exact``); ``a``,
    ``b``: the links' indices in the collision model, ``pair`` the pair's. Nodes where the
    hulls come within ``refine`` mm get the meshes' own distance.

    ``sweep = (sweep_a, sweep_b)``: link a is replaced by its turn about the first joint
    after it, link b by its turn about its own joint (``swept_slabs`` of ``triangles_a``
    or ``triangles_b``, each link's geometry ``(T, 3, 3)`` in its frame), and that joint
    leaves the table: the swept solid contains the link at every angle, so its distance is
    a lower bound at every angle of the swept joint, and links three or four joints apart
    get tables over the two joints between."""
    import fcl

    la, lb = robot.links[link_a], robot.links[link_b]
    if robot.model.convention != "poe" or getattr(la, "mimic", ()) or getattr(lb, "mimic", ()):
        return None
    model = robot.model
    chain = np.arange(la.frame, lb.frame)           # chain joints frame_a+1 .. frame_b
    sweep_a, sweep_b = bool(sweep[0]), bool(sweep[1])
    joints = chain[int(sweep_a):len(chain) - int(sweep_b)]
    k = len(joints)
    if k not in (1, 2) or len(chain) != k + sweep_a + sweep_b:
        return None

    def revolute(j: int) -> bool:
        return bool(model.joints[j].revolute and model.joints[j].point is not None)

    def axis_point(j: int) -> np.ndarray:
        return _axis(model, j)[0]

    def axis_in(T: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        return _axis_in(model, T, j)

    mid = model.mid_configuration()
    # The distances that bound rho do not depend on the joints: take them at q = 0, where
    # the product-of-exponentials axis points are the model's own (base frame).
    P0 = robot.link_poses(np.zeros(model.dof))
    T_b = P0[link_b]
    if sweep_a or sweep_b:
        for on, j, tri in ((sweep_a, chain[0], triangles_a), (sweep_b, chain[-1], triangles_b)):
            if on and (not revolute(j) or tri is None or len(tri) == 0):
                return None
        if sweep_a:
            shapes_a = [_SweptShape(V) for V in
                        swept_slabs(triangles_a, *axis_in(P0[link_a], chain[0]))]
        if sweep_b:
            pieces = swept_slabs(triangles_b, *axis_in(T_b, chain[-1]))
            shapes_b = [_SweptShape(V) for V in pieces]
            V_b = np.vstack(pieces)
            c = 0.5 * (V_b.min(axis=0) + V_b.max(axis=0))
            ball_b = (c, float(np.linalg.norm(V_b - c, axis=1).max()))
    centre = T_b[:3, :3] @ np.asarray(ball_b[0]) + T_b[:3, 3]
    rho = np.empty(k)
    outer = float(np.linalg.norm(centre - axis_point(joints[-1])) + ball_b[1]) \
        if revolute(joints[-1]) else 0.0
    for i in range(k - 1, -1, -1):
        j = joints[i]
        if not revolute(j):
            rho[i] = 1.0
        elif i == k - 1:
            rho[i] = outer
        elif revolute(joints[-1]):
            rho[i] = float(np.linalg.norm(axis_point(joints[-1]) - axis_point(j))) + outer
        else:
            return None  # a prismatic joint outside a revolute one: no simple bound
    if not sweep_a and revolute(joints[0]) and triangles_a is not None and len(triangles_a):
        # d(a, R(q) b) = d(R(-q) a, b): the first joint's axis is fixed to link a, so its
        # turn also moves the distance by at most a's farthest point from that axis (a
        # base about its own vertical axis: its radius, not the arm's reach).
        point, axis = axis_in(P0[link_a], joints[0])
        rel = np.asarray(triangles_a, dtype=float).reshape(-1, 3) - point
        u = axis / np.linalg.norm(axis)
        reach_a = float(np.linalg.norm(rel - np.outer(rel @ u, u), axis=1).max())
        rho[0] = min(rho[0], reach_a)
    lo = np.asarray(model.lower)[joints].astype(float)
    span = np.asarray(model.upper)[joints] - lo
    step = np.maximum(2 * tolerance / (k * np.maximum(rho, 1e-9)), 1e-6)
    n = np.maximum(np.ceil(span / step).astype(int) + 1, 2)
    if n.prod() > max_nodes:
        n = np.maximum(np.floor(n * (max_nodes / n.prod()) ** (1 / k)).astype(int), 2)
    step = np.where(span > 0, span / (n - 1), 1.0)
    balls_a = [_ball(s) for s in shapes_a]
    balls_b = [_ball(s) for s in shapes_b]
    hull_a = _Side([fcl.CollisionObject(_hull_geometry(s), _tf(s.T)) for s in shapes_a],
                   shapes_a, balls_a)
    hull_b = _Side([fcl.CollisionObject(_hull_geometry(s), _tf(s.T)) for s in shapes_b],
                   shapes_b, balls_b)
    mesh_a = _Side([fcl.CollisionObject(s.geom, _tf(s.T)) for s in shapes_a], shapes_a, balls_a)
    mesh_b = _Side([fcl.CollisionObject(s.geom, _tf(s.T)) for s in shapes_b], shapes_b, balls_b)
    convex = all(s.kind != "mesh" for s in (*shapes_a, *shapes_b))

    def exact(idx: np.ndarray) -> np.ndarray:
        """FCL distances at grid nodes ``idx (N, k)``: the hulls', and the meshes' where
        the hulls come within ``refine`` mm (concave links that nest are not held in
        contact by their hulls)."""
        Q = np.repeat(mid[None], len(idx), axis=0)
        Q[:, joints] = lo + idx * step
        # A swept joint at 0: the swept solids were made at q = 0 (any angle would do).
        Q[:, chain[:int(sweep_a)]] = 0.0
        if sweep_b:
            Q[:, chain[-1]] = 0.0
        P = robot.link_poses(Q)
        rel = np.linalg.inv(P[:, link_a]) @ P[:, link_b]
        out = np.array([_distance(hull_a, hull_b, R) for R in rel])
        if not convex:
            for i in np.flatnonzero(out < refine):
                out[i] = _distance(mesh_a, mesh_b, rel[i])
        return out

    values = _adaptive_values(tuple(int(x) for x in n), rho * step,
                              float((rho * step).sum()) + exact_margin, exact)
    return PairTable(a, b, pair, joints, lo, step, tuple(int(x) for x in n), rho, values,
                     ("a" if sweep_a else "") + ("b" if sweep_b else ""))


def _axis(model: Any, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Revolute joint ``j``'s axis (point, unit direction) in the world at q = 0."""
    R, t = model.base[:3, :3], model.base[:3, 3]
    d = R @ np.asarray(model.joints[j].axis or (0.0, 0.0, 1.0), dtype=float)
    return R @ np.asarray(model.joints[j].point, dtype=float) + t, d / np.linalg.norm(d)


def _axis_in(model: Any, T: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Joint ``j``'s axis (point, direction) in the frame of pose ``T`` (both at q = 0)."""
    point, d = _axis(model, j)
    R = T[:3, :3].T
    return R @ (point - T[:3, 3]), R @ d


def sweep_ratio(robot: Any, link: int, joint: int, triangles: np.ndarray) -> float:
    """How much room turning link ``link`` (index into ``robot.links``; geometry
    ``triangles (T, 3, 3)`` in its frame) about chain joint ``joint`` adds: the volume of
    its swept solid (``swept_slabs``) over that of its convex hull (1 for a solid of
    revolution about the joint; ``inf`` for a joint that is not revolute or flat geometry).
    """
    from scipy.spatial import ConvexHull

    model = robot.model
    j = model.joints[joint]
    if not (j.revolute and j.point is not None) or len(triangles) == 0:
        return math.inf
    T0 = robot.link_poses(np.zeros(model.dof))[link]
    try:
        own = ConvexHull(np.asarray(triangles, dtype=float).reshape(-1, 3)).volume
        swept = sum(ConvexHull(V).volume
                    for V in swept_slabs(triangles, *_axis_in(model, T0, joint)))
    except Exception:  # noqa: BLE001 - flat geometry (qhull refuses it)
        return math.inf
    return float(swept / own) if own > 0 else math.inf


#: The swept solids (``swept_slabs``): sides of the polygon that circumscribes each circle
#: (its corners at ``1 / cos(pi / SWEEP_SIDES)`` times the radius, 0.9 % out at 24), slabs
#: cut along the axis first, and how much wider (mm) a run of slabs may be than its
#: narrowest before it is cut in two.
SWEEP_SIDES = 24
SWEEP_SLABS = 64
SWEEP_MERGE = 2.0


def swept_slabs(triangles: np.ndarray, point: np.ndarray, axis: np.ndarray,
                sides: int = SWEEP_SIDES, slabs: int = SWEEP_SLABS,
                merge: float = SWEEP_MERGE) -> list[np.ndarray]:
    """Vertices ``(V, 3)`` of convex prisms about the axis through ``point`` along
    ``axis`` whose union contains ``triangles (T, 3, 3)`` turned by every angle about the
    axis (a solid of revolution: a lathe's stack of discs).

    The geometry's extent along the axis is cut into ``slabs``; a slab's radius is the
    largest distance from the axis of the geometry inside it. The distance from a line is
    convex, so over a triangle clipped to a slab it is largest at a corner of the clipped
    polygon: a triangle corner inside the slab or where an edge crosses one of the slab's
    planes; both kinds are measured. (The inside of a closed surface lies between surface
    points of the same height, so it is covered too.) Runs of slabs whose radii differ by
    at most ``merge`` mm become one prism of their largest radius; each prism is a
    ``sides``-gon pushed out to contain its circle."""
    X = np.asarray(triangles, dtype=float).reshape(-1, 3, 3)
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)

    def cyl(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rel = P - point
        z = rel @ u
        return z, np.linalg.norm(rel - z[..., None] * u, axis=-1)

    z, r = cyl(X.reshape(-1, 3))
    lo, hi = float(z.min()), float(z.max())
    h = max(hi - lo, 1e-9) / slabs
    planes = lo + h * np.arange(slabs + 1)
    R = np.zeros(slabs)
    np.maximum.at(R, np.clip(((z - lo) / h).astype(np.intp), 0, slabs - 1), r)
    # Edges against every slab plane: the crossing points bound both neighbouring slabs.
    P, Q = X.reshape(-1, 3), np.roll(X, -1, axis=1).reshape(-1, 3)
    zp, zq = cyl(P)[0], cyl(Q)[0]
    for i, c in enumerate(planes):
        hit = (np.minimum(zp, zq) <= c) & (np.maximum(zp, zq) >= c) & (zp != zq)
        if not hit.any():
            continue
        t = ((c - zp[hit]) / (zq[hit] - zp[hit]))[:, None]
        rc = cyl(P[hit] + t * (Q[hit] - P[hit]))[1].max()
        for j in (i - 1, i):
            if 0 <= j < slabs:
                R[j] = max(R[j], rc)
    a = 2 * np.pi * np.arange(sides) / sides
    ring = (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2) / math.cos(math.pi / sides)
    pieces, i = [], 0
    while i < slabs:
        j = i
        while j + 1 < slabs and max(R[i:j + 2]) - min(R[i:j + 2]) <= merge:
            j += 1
        radius = float(R[i:j + 1].max()) * (1 + 1e-9) + 1e-6
        ends = (planes[i] - 1e-6, planes[j + 1] + 1e-6)
        pieces.append(np.vstack([point + z0 * u + radius * ring for z0 in ends]))
        i = j + 1
    return pieces


class _SweptShape:
    """A swept solid as an exact shape of the table's builder: a convex polytope in the
    link's frame."""

    kind = "swept"

    def __init__(self, vertices: np.ndarray) -> None:
        self.T = np.eye(4)
        self.data: dict = {}
        self.vertices = vertices
        self.geom = _convex(vertices)


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


@dataclass
class _Side:
    """One link's FCL objects in a table's distance, with their shapes (``T``: link ->
    shape) and bounding balls (centre in the link's frame, radius)."""

    objects: list
    shapes: list
    balls: list


def _ball(shape: Any) -> tuple[np.ndarray, float]:
    """A ball containing an exact shape, in its owner's frame (centre, radius)."""
    T, data = shape.T, shape.data
    if shape.kind in ("mesh", "swept"):
        V = data["triangles"].reshape(-1, 3) if shape.kind == "mesh" else shape.vertices
        V = V @ T[:3, :3].T + T[:3, 3]
        c = 0.5 * (V.min(axis=0) + V.max(axis=0))
        return c, float(np.linalg.norm(V - c, axis=1).max())
    if shape.kind == "box":
        r = 0.5 * float(np.linalg.norm(data["size"]))
    elif shape.kind == "cylinder":
        r = math.hypot(data["radius"], 0.5 * data["height"])
    elif shape.kind == "capsule":
        r = data["radius"] + 0.5 * data["height"]
    else:
        r = data["radius"]
    return T[:3, 3].copy(), r * (1 + 1e-9) + 1e-9


def _distance(side_a: _Side, side_b: _Side, R: np.ndarray) -> float:
    """Least FCL distance (0 when touching) between the shapes of link a (in its frame) and
    of link b placed at ``R = T_a_b``: pairs in the order of their balls' distance, none
    whose balls lie farther apart than the least distance found."""
    import fcl

    ca = np.array([c for c, _ in side_a.balls])
    ra = np.array([r for _, r in side_a.balls])
    cb = np.array([c for c, _ in side_b.balls]) @ R[:3, :3].T + R[:3, 3]
    rb = np.array([r for _, r in side_b.balls])
    lb = np.linalg.norm(ca[:, None] - cb[None], axis=-1) - ra[:, None] - rb[None]
    best = math.inf
    request = fcl.DistanceRequest()
    posed = set()
    for flat in np.argsort(lb, axis=None):
        i, j = divmod(int(flat), lb.shape[1])
        if lb[i, j] >= best:
            break
        ob = side_b.objects[j]
        if j not in posed:
            ob.setTransform(_tf(R @ side_b.shapes[j].T))
            posed.add(j)
        d = fcl.distance(side_a.objects[i], ob, request, fcl.DistanceResult())
        best = min(best, 0.0 if d < 0 else d)
        if best == 0.0:
            break
    return best


def _hull_geometry(shape: Any):
    """FCL geometry of a shape's convex hull (the shape itself for a primitive)."""
    if shape.kind != "mesh":
        return shape.geom
    return _convex(shape.data["triangles"].reshape(-1, 3))


def _convex(V: np.ndarray):
    """FCL convex geometry of the convex hull of points ``V (N, 3)``."""
    import fcl
    from scipy.spatial import ConvexHull

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
