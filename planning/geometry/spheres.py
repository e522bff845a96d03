"""Conservative sphere coverings of geometry: the ball sets of the sphere stage.

Everything here rests on one fact: a ball contains a convex set exactly when it contains
the set's extreme points. The geometry is cut into convex pieces, each piece's extreme
points are computed exactly, and each ball's radius is the largest distance from its centre
to the points it must contain. So the union of the balls contains the geometry, whatever the
choice of cuts and centres; the choices only make the balls tighter or looser.

* Robot links (``cover_link``): the link's geometry is split by planes into cells, greedily
  (a binary space partition): the cell whose best split (along its three principal axes, at
  three quantiles) shrinks the total ball volume most is split next, first into
  ``n_groups`` groups, then each group into ``per_group`` leaves. Each leaf's ball contains
  the geometry inside the leaf's cell: the link's triangles clipped to the cell (exact
  polygons, Sutherland-Hodgman) and its convex solids (box, cylinder, sphere, through
  circumscribing polytopes) intersected with the cell (exact vertices, qhull). Each group's
  ball contains its leaves' balls, the root ball contains the groups': a three-level tree.
* Scene meshes and point clouds (``cover_triangles``, ``cover_points``): a uniform grid of
  cubes; a ball per occupied cube around the triangles clipped to it, or around its points
  inflated by their radius.

Meshes are covered as surfaces (their triangles), as the exact stage (FCL's triangle
models) treats them; solids (boxes, cylinders, spheres) as solids. Lengths in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "SphereTree",
    "ConvexSolid",
    "box_solid",
    "cylinder_solid",
    "sphere_solid",
    "clip_polygons",
    "enclosing_ball",
    "enclosing_balls",
    "enclosing_ball_of_balls",
    "cover_link",
    "cover_triangles",
    "cover_points",
]

#: Relative and absolute slack (mm) added to every enclosing radius against round-off.
RADIUS_SLACK = (1e-9, 1e-6)
#: Sides of the prism that circumscribes a cylinder, and directions of the polytope that
#: circumscribes a sphere.
CYLINDER_SIDES = 32
SPHERE_DIRECTIONS = 96
#: Points sampled on a link's surfaces and in its solids to steer the splits (fixed seed:
#: the covering is the same on every build).
STEER_SAMPLES = 4000
STEER_SEED = 20240611


@dataclass(frozen=True)
class SphereTree:
    """A three-level sphere tree in one frame: ``root (4,)``, ``groups (G, 4)``,
    ``leaves (G, m, 4)`` as ``[x, y, z, radius]`` (mm). Groups with fewer distinct leaves
    repeat one (harmless for distances). ``unique (K, 4)``: the distinct leaves."""

    root: np.ndarray
    groups: np.ndarray
    leaves: np.ndarray
    unique: np.ndarray


@dataclass(frozen=True)
class ConvexSolid:
    """A convex solid as half-spaces ``A x + b <= 0`` (``halfspaces (H, 4)`` = ``[A | b]``)
    and its vertices ``(V, 3)``."""

    halfspaces: np.ndarray
    vertices: np.ndarray


# ---- convex solids --------------------------------------------------------------------------
def _posed(halfspaces: np.ndarray, vertices: np.ndarray, T: np.ndarray) -> ConvexSolid:
    """A solid given in its own frame, moved by ``T`` (4, 4)."""
    R, t = T[:3, :3], T[:3, 3]
    A = halfspaces[:, :3] @ R.T
    b = halfspaces[:, 3] - A @ t
    return ConvexSolid(np.column_stack([A, b]), vertices @ R.T + t)


def box_solid(size, T: np.ndarray) -> ConvexSolid:
    """A box of full sides ``size`` centred on the origin of pose ``T``."""
    h = 0.5 * np.asarray(size, dtype=float)
    H = np.zeros((6, 4))
    for k in range(3):
        H[2 * k, k], H[2 * k, 3] = 1.0, -h[k]
        H[2 * k + 1, k], H[2 * k + 1, 3] = -1.0, -h[k]
    V = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    return _posed(H, V, T)


def cylinder_solid(radius: float, height: float, T: np.ndarray) -> ConvexSolid:
    """The prism of ``CYLINDER_SIDES`` sides circumscribing a cylinder (axis local z,
    centred) of pose ``T``: it contains the cylinder."""
    n = CYLINDER_SIDES
    a = 2 * np.pi * np.arange(n) / n
    H = np.zeros((n + 2, 4))
    H[:n, 0], H[:n, 1], H[:n, 3] = np.cos(a), np.sin(a), -radius
    H[n, 2], H[n, 3] = 1.0, -0.5 * height
    H[n + 1, 2], H[n + 1, 3] = -1.0, -0.5 * height
    rc = radius / math.cos(math.pi / n)
    ring = np.column_stack([rc * np.cos(a + np.pi / n), rc * np.sin(a + np.pi / n)])
    V = np.vstack([np.column_stack([ring, np.full(n, z)]) for z in (-0.5 * height,
                                                                     0.5 * height)])
    return _posed(H, V, T)


def sphere_solid(radius: float, T: np.ndarray) -> ConvexSolid:
    """A polytope circumscribing a ball of ``radius`` at the origin of ``T``: tangent planes
    at ``SPHERE_DIRECTIONS`` near-uniform directions (a Fibonacci lattice)."""
    from scipy.spatial import HalfspaceIntersection

    n = SPHERE_DIRECTIONS
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5 ** 0.5) * k
    U = np.column_stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])
    H = np.column_stack([U, np.full(n, -radius)])
    V = HalfspaceIntersection(H, np.zeros(3)).intersections
    return _posed(H, V, T)


def _solid_piece(solid: ConvexSolid, planes: np.ndarray) -> np.ndarray:
    """Vertices ``(V, 3)`` of ``solid`` cut by ``planes (P, 4)`` (``n x + d <= 0`` kept);
    empty when the piece has no volume (a piece that only touches the cell's boundary is
    also part of the neighbouring cell, which covers it)."""
    if len(planes) == 0:
        return solid.vertices
    from scipy.optimize import linprog
    from scipy.spatial import HalfspaceIntersection

    H = np.vstack([solid.halfspaces, planes])
    norms = np.linalg.norm(H[:, :3], axis=1)
    # The deepest point (Chebyshev centre): maximise s with A x + s |A| <= -b.
    res = linprog(np.r_[0.0, 0.0, 0.0, -1.0], A_ub=np.column_stack([H[:, :3], norms]),
                  b_ub=-H[:, 3], bounds=[(None, None)] * 3 + [(0, None)], method="highs")
    if res.status != 0 or res.x[3] <= 1e-9:
        return np.empty((0, 3))
    return HalfspaceIntersection(H, res.x[:3]).intersections


# ---- polygons -----------------------------------------------------------------------------
def clip_polygons(P: np.ndarray, count: np.ndarray, normal: np.ndarray, offset
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Clip convex polygons to the half-space ``normal . x + offset <= 0``
    (Sutherland-Hodgman, vectorised).

    ``P (N, M, 3)``: vertices in order, the first ``count (N,)`` of each row valid;
    ``normal (3,)`` or ``(N, 3)``, ``offset`` scalar or ``(N,)``. Returns
    ``(P' (N, M + 1, 3), count' (N,))``; a polygon wholly outside gets count 0. Only the
    polygons the plane crosses are recomputed."""
    N, M, _ = P.shape
    normal = np.broadcast_to(np.asarray(normal, dtype=float), (N, 3))
    offset = np.broadcast_to(np.asarray(offset, dtype=float), (N,))
    s = np.einsum("nmj,nj->nm", P, normal) + offset[:, None]
    idx = np.arange(M)
    valid = idx[None] < count[:, None]
    inside = s <= 0
    all_in = np.all(inside | ~valid, axis=1)
    all_out = np.all(~inside | ~valid, axis=1)
    out = np.concatenate([P, P[:, :1]], axis=1)
    new_count = np.where(all_out, 0, count)
    rows = np.flatnonzero(~all_in & ~all_out)
    if len(rows) == 0:
        return out, new_count
    Pc, sc, cc, vc = P[rows], s[rows], count[rows], valid[rows]
    nxt = np.where(idx[None] + 1 < cc[:, None], idx[None] + 1, 0)
    Pn = np.take_along_axis(Pc, nxt[..., None], axis=1)
    sn = np.take_along_axis(sc, nxt, axis=1)
    ins, ins_n = sc <= 0, sn <= 0
    cross = vc & (ins != ins_n)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(cross, sc / (sc - sn), 0.0)
    X = Pc + t[..., None] * (Pn - Pc)
    # Per edge: the start vertex if inside, then the crossing if any: 2 slots per edge.
    cand = np.stack([Pc, X], axis=2).reshape(len(rows), 2 * M, 3)
    keep = np.stack([vc & ins, cross], axis=2).reshape(len(rows), 2 * M)
    order = np.argsort(~keep, axis=1, kind="stable")[:, :M + 1]
    out[rows] = np.take_along_axis(cand, order[..., None], axis=1)
    new_count[rows] = np.minimum(keep.sum(1), M + 1)
    return out, new_count


def _clip_all(P: np.ndarray, count: np.ndarray, planes: list
              ) -> tuple[np.ndarray, np.ndarray]:
    """Polygons clipped to every plane ``(normal, threshold)`` (``normal . x <= thr``
    kept), the empty ones dropped."""
    for normal, thr in planes:
        P, count = clip_polygons(P, count, normal, -thr)
        alive = count > 0
        P, count = P[alive], count[alive]
        P = P[:, :max(int(count.max(initial=0)), 1)]
    return P, count


def _points_of(P: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The valid vertices of polygons ``(N, M, 3)`` as one ``(n, 3)`` array."""
    mask = np.arange(P.shape[1])[None] < count[:, None]
    return P[mask]


# ---- enclosing balls ----------------------------------------------------------------------
def _slack(r):
    return r * (1 + RADIUS_SLACK[0]) + RADIUS_SLACK[1]


def enclosing_ball(P: np.ndarray, iterations: int = 300) -> tuple[np.ndarray, float]:
    """A ball ``(centre (3,), radius)`` containing the points ``P (n, 3)``: near the
    smallest one (Badoiu-Clarkson steps from the bounding box centre, on the convex hull's
    vertices), and always containing every point (the radius is the largest distance)."""
    P = np.asarray(P, dtype=float)
    if len(P) > 8:
        try:
            from scipy.spatial import ConvexHull

            P = P[ConvexHull(P).vertices]
        except Exception:  # noqa: BLE001 - flat or degenerate sets: keep every point
            pass
    c = 0.5 * (P.min(0) + P.max(0))
    for i in range(iterations):
        far = P[np.argmax(np.square(P - c).sum(1))]
        c = c + (far - c) / (i + 2)
    return c, float(_slack(np.sqrt(np.square(P - c).sum(1).max())))


def enclosing_balls(sets: list[np.ndarray], iterations: int = 300
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``enclosing_ball`` of several point sets at once: centres ``(K, 3)`` and radii
    ``(K,)``; the same steps, run on all sets together (each padded with its own first
    point, which changes no farthest point)."""
    from scipy.spatial import ConvexHull

    hulls = []
    for P in sets:
        P = np.asarray(P, dtype=float)
        if len(P) > 8:
            try:
                P = P[ConvexHull(P).vertices]
            except Exception:  # noqa: BLE001 - flat or degenerate sets: keep every point
                pass
        hulls.append(P)
    m = max(len(P) for P in hulls)
    X = np.stack([np.vstack([P, np.repeat(P[:1], m - len(P), axis=0)]) for P in hulls])
    c = 0.5 * (X.min(1) + X.max(1))
    rows = np.arange(len(X))
    for i in range(iterations):
        far = X[rows, np.argmax(np.square(X - c[:, None]).sum(-1), axis=1)]
        c = c + (far - c) / (i + 2)
    r = np.sqrt(np.square(X - c[:, None]).sum(-1).max(axis=1))
    return c, _slack(r)


def enclosing_ball_of_balls(C: np.ndarray, R: np.ndarray, start=None,
                            iterations: int = 300) -> tuple[np.ndarray, float]:
    """A ball containing the balls ``C (n, 3)``, ``R (n,)``: steps towards the farthest
    ball's far side, and the radius is ``max |c - C_k| + R_k``."""
    c = C.mean(0) if start is None else np.asarray(start, dtype=float)
    for i in range(iterations):
        d = np.linalg.norm(C - c, axis=1)
        k = int(np.argmax(d + R))
        u = (C[k] - c) / d[k] if d[k] > 0 else np.zeros(3)
        c = c + (C[k] + R[k] * u - c) / (i + 2)
    return c, float(_slack((np.linalg.norm(C - c, axis=1) + R).max()))


# ---- robot links ----------------------------------------------------------------------------
def _steering_points(triangles: np.ndarray, solids: list[ConvexSolid]) -> np.ndarray:
    """Points spread over the triangles (area-weighted, plus their corners) and inside the
    solids, to choose the splits."""
    rng = np.random.default_rng(STEER_SEED)
    pts = []
    if len(triangles):
        area = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0],
                                             triangles[:, 2] - triangles[:, 0]), axis=1)
        n = STEER_SAMPLES // (1 + len(solids))
        if area.sum() > 0:
            pick = rng.choice(len(triangles), size=n, p=area / area.sum())
            u, v = rng.random((2, n))
            flip = u + v > 1
            u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
            T = triangles[pick]
            pts.append(T[:, 0] + u[:, None] * (T[:, 1] - T[:, 0])
                       + v[:, None] * (T[:, 2] - T[:, 0]))
        corners = np.unique(triangles.reshape(-1, 3), axis=0)
        if len(corners) > STEER_SAMPLES:
            corners = corners[rng.choice(len(corners), STEER_SAMPLES, replace=False)]
        pts.append(corners)
    for s in solids:
        lo, hi = s.vertices.min(0), s.vertices.max(0)
        X = lo + rng.random((STEER_SAMPLES // (1 + len(solids)), 3)) * (hi - lo)
        inside = np.all(X @ s.halfspaces[:, :3].T + s.halfspaces[:, 3] <= 0, axis=1)
        pts.append(X[inside])
        pts.append(s.vertices)
    return np.vstack(pts)


def _hull_facets(X: np.ndarray) -> np.ndarray:
    """Facets ``(H, 4)`` of the convex hull of ``X`` (a box around a flat set)."""
    from scipy.spatial import ConvexHull

    try:
        return ConvexHull(X).equations
    except Exception:  # noqa: BLE001 - flat sets: their bounding box, slightly thickened
        lo, hi = X.min(0) - 1e-3, X.max(0) + 1e-3
        eye = np.eye(3)
        return np.vstack([np.column_stack([eye, -hi]), np.column_stack([-eye, lo])])


def _rough_ball(X: np.ndarray) -> tuple[np.ndarray, float]:
    c = 0.5 * (X.min(0) + X.max(0))
    return c, float(np.sqrt(np.square(X - c).sum(1).max()))


def _protrusion(X: np.ndarray, hull: np.ndarray) -> float:
    """How far the rough ball around points ``X`` sticks out of the link's convex hull
    (facets ``hull (H, 4)``, ``n x + d <= 0`` inside): ``r + max_f (n_f c + d_f)``, the
    largest value on the ball of the hull's signed distance (its lower bound outside)."""
    c, r = _rough_ball(X)
    return r + float((hull[:, :3] @ c + hull[:, 3]).max())


_QUANTILES = np.linspace(0.1, 0.9, 9)


def _best_split(X: np.ndarray, hull: np.ndarray
                ) -> tuple[tuple[float, float], np.ndarray, float] | None:
    """The split of steering points ``X`` whose two balls stick out least (the larger
    protrusion, then the sum), among planes across the principal and the frame's axes at
    nine quantiles: ``(cost, normal, threshold)``, the left side ``normal . x <= thr``.

    Every candidate at once: per axis the points sorted once, the two sides' bounding
    boxes from running minima and maxima, their radii from one matrix product."""
    n = len(X)
    if n < 4:
        return None
    _, _, Vt = np.linalg.svd(X - X.mean(0), full_matrices=False)
    axes = np.vstack([Vt, np.eye(3)])                       # (A, 3)
    S = X @ axes.T                                          # (n, A)
    thr = np.quantile(S, _QUANTILES, axis=0).T              # (A, K)
    order = np.argsort(S, axis=0, kind="stable")            # (n, A)
    s_sorted = np.take_along_axis(S, order, axis=0)
    A, K = thr.shape
    count = np.empty((A, K), dtype=np.intp)                 # points on the left
    for a in range(A):
        count[a] = np.searchsorted(s_sorted[:, a], thr[a], side="right")
    Xs = X[order.T]                                         # (A, n, 3)
    lo_l = np.minimum.accumulate(Xs, axis=1)
    hi_l = np.maximum.accumulate(Xs, axis=1)
    lo_r = np.minimum.accumulate(Xs[:, ::-1], axis=1)[:, ::-1]
    hi_r = np.maximum.accumulate(Xs[:, ::-1], axis=1)[:, ::-1]
    valid = (count > 0) & (count < n)
    cl = np.clip(count - 1, 0, n - 1)
    cr = np.clip(count, 0, n - 1)
    ar = np.arange(A)[:, None]
    c_left = 0.5 * (lo_l[ar, cl] + hi_l[ar, cl])            # (A, K, 3)
    c_right = 0.5 * (lo_r[ar, cr] + hi_r[ar, cr])
    C = np.concatenate([c_left, c_right], axis=1)           # (A, 2K, 3)
    # |x - c|^2 = |x|^2 - 2 x.c + |c|^2 for every point and centre (one product).
    sq = np.einsum("ij,ij->i", X, X)
    Cf = C.reshape(-1, 3)
    G = sq[:, None] - 2.0 * (X @ Cf.T) + np.square(Cf).sum(1)[None]   # (n, A * 2K)
    G = G.reshape(n, A, 2, K)
    left = S[:, :, None] <= thr[None]                       # (n, A, K)
    r2_left = np.where(left, G[:, :, 0], -np.inf).max(axis=0)
    r2_right = np.where(left, -np.inf, G[:, :, 1]).max(axis=0)
    out = C.reshape(-1, 3) @ hull[:, :3].T + hull[:, 3]     # (A * 2K, H)
    out = out.max(axis=1).reshape(A, 2, K)
    p1 = np.sqrt(np.maximum(r2_left, 0.0)) + out[:, 0]
    p2 = np.sqrt(np.maximum(r2_right, 0.0)) + out[:, 1]
    worst = np.where(valid, np.maximum(p1, p2), np.inf).ravel()
    total = np.where(valid, p1 + p2, np.inf).ravel()
    if not np.isfinite(worst).any():
        return None
    k = int(np.lexsort((total, worst))[0])
    a, j = divmod(k, K)
    return (float(worst[k]), float(total[k])), axes[a], float(thr[a, j])


@dataclass
class _Cell:
    planes: list          # [(normal (3,), threshold)]: normal . x <= threshold
    X: np.ndarray         # steering points inside


def _partition(cell: _Cell, n: int, hull: np.ndarray) -> list[_Cell]:
    """Split ``cell`` greedily into at most ``n`` cells: next, the cell that sticks out
    most among those a split improves (its children stick out less than it); when no split
    improves any cell, the one it harms least."""
    cells = [cell]
    splits = [_best_split(cell.X, hull)]
    stick = [_protrusion(cell.X, hull)]
    while len(cells) < n:
        better = [(p if s is not None and s[0][0] < p else -np.inf)
                  for p, s in zip(stick, splits)]
        k = int(np.argmax(better))
        if better[k] == -np.inf:
            gains = [(-np.inf if s is None else p - s[0][0]) for p, s in zip(stick, splits)]
            k = int(np.argmax(gains))
            if gains[k] == -np.inf:
                break
        _, axis, thr = splits[k]
        c = cells.pop(k)
        splits.pop(k)
        stick.pop(k)
        s = c.X @ axis
        for child in (_Cell(c.planes + [(axis, thr)], c.X[s <= thr]),
                      _Cell(c.planes + [(-axis, -thr)], c.X[s > thr])):
            cells.append(child)
            splits.append(_best_split(child.X, hull))
            stick.append(_protrusion(child.X, hull) if len(child.X) else -np.inf)
    return cells


def _cell_points(polygons: tuple[np.ndarray, np.ndarray], solids: list[ConvexSolid],
                 planes: list, extra: list) -> np.ndarray:
    """The extreme points of the geometry inside the cell ``planes``: the polygons (already
    clipped to all but the ``extra`` planes) clipped to it, and the solids cut by it."""
    P, count = _clip_all(*polygons, extra)
    pts = [_points_of(P, count)]
    H = np.array([[*normal, -thr] for normal, thr in planes]).reshape(-1, 4)
    for s in solids:
        pts.append(_solid_piece(s, H))
    return np.vstack(pts)


def cover_link(triangles: np.ndarray, solids: list[ConvexSolid], n_groups: int = 4,
               per_group: int = 4) -> SphereTree:
    """A sphere tree covering a link: ``triangles (T, 3, 3)`` (its meshes, in the link
    frame, mm) and convex ``solids``; at most ``n_groups * per_group`` leaves."""
    X = _steering_points(triangles, solids)
    hull = _hull_facets(X)
    groups, leaves = [], []
    everything = (triangles.reshape(-1, 3, 3).copy(), np.full(len(triangles), 3))
    pieces, owner = [], []
    for gi, g in enumerate(_partition(_Cell([], X), n_groups, hull)):
        inside = _clip_all(*everything, g.planes)
        for leaf in _partition(_Cell(list(g.planes), g.X), per_group, hull):
            P = _cell_points(inside, solids, leaf.planes, leaf.planes[len(g.planes):])
            if len(P):
                pieces.append(P)
                owner.append(gi)
    if not pieces:
        raise ValueError("the link has no geometry to cover")
    centres, radii = enclosing_balls(pieces)
    owner = np.array(owner)
    for gi in np.unique(owner):
        B = np.column_stack([centres[owner == gi], radii[owner == gi]])
        c, r = enclosing_ball_of_balls(B[:, :3], B[:, 3])
        groups.append([*c, r])
        leaves.append(B)
    if not groups:
        raise ValueError("the link has no geometry to cover")
    G = np.array(groups)
    m = max(len(b) for b in leaves)
    padded = np.stack([np.vstack([b, np.repeat(b[:1], m - len(b), axis=0)]) for b in leaves])
    c, r = enclosing_ball_of_balls(G[:, :3], G[:, 3])
    return SphereTree(np.array([*c, r]), G, padded, np.vstack(leaves))


# ---- scene meshes and point clouds ------------------------------------------------------
def _balls_by_cell(points: np.ndarray, cell: np.ndarray, extra) -> np.ndarray:
    """One ball ``[x, y, z, r]`` per distinct ``cell`` id: centred on the bounding box of
    its points, radius the largest distance plus ``extra`` (scalar or per point)."""
    order = np.argsort(cell, kind="stable")
    cell, points = cell[order], points[order]
    extra = np.broadcast_to(np.asarray(extra, dtype=float), (len(points),))[order]
    starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
    lo = np.minimum.reduceat(points, starts, axis=0)
    hi = np.maximum.reduceat(points, starts, axis=0)
    centre = 0.5 * (lo + hi)
    owner = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(points)]))
    d = np.linalg.norm(points - centre[owner], axis=1) + extra
    r = np.maximum.reduceat(d, starts)
    return np.column_stack([centre, _slack(r)])


def cover_points(points: np.ndarray, radius: float, resolution: float) -> np.ndarray:
    """Balls ``(K, 4)`` covering the balls of ``radius`` around ``points (N, 3)``: one per
    occupied cube of side ``resolution``."""
    key = np.floor(points / resolution).astype(np.int64)
    _, cell = np.unique(key, axis=0, return_inverse=True)
    return _balls_by_cell(points, cell.ravel(), radius)


def cover_triangles(triangles: np.ndarray, cell_size: float, chunk: int = 50_000
                    ) -> np.ndarray:
    """Balls ``(K, 4)`` covering ``triangles (T, 3, 3)``: the triangles clipped to the cubes
    of side ``cell_size`` they cross, one ball per cube."""
    lo = np.floor(triangles.min(1) / cell_size).astype(np.int64)
    hi = np.floor(triangles.max(1) / cell_size).astype(np.int64)
    span = hi - lo + 1
    n = span.prod(1)
    pts_all, keys_all = [], []
    tri_of = np.repeat(np.arange(len(triangles)), n)
    offset = np.arange(len(tri_of)) - np.repeat(np.cumsum(n) - n, n)
    for s in range(0, len(tri_of), chunk):
        t = tri_of[s:s + chunk]
        o = offset[s:s + chunk]
        sp = span[t]
        ijk = np.column_stack([o // (sp[:, 1] * sp[:, 2]), (o // sp[:, 2]) % sp[:, 1],
                               o % sp[:, 2]]) + lo[t]
        P = triangles[t]
        count = np.full(len(t), 3)
        for k in range(3):
            e = np.zeros(3)
            e[k] = 1.0
            P, count = clip_polygons(P, count, e, -(ijk[:, k] + 1) * cell_size)
            P, count = clip_polygons(P, count, -e, ijk[:, k] * cell_size)
        alive = count > 0
        P, count, ijk = P[alive], count[alive], ijk[alive]
        P = P[:, :count.max(initial=0)] if len(P) else P
        mask = np.arange(P.shape[1])[None] < count[:, None]
        pts_all.append(P[mask])
        keys_all.append(np.repeat(ijk, count, axis=0))
    pts = np.vstack(pts_all)
    keys = np.vstack(keys_all)
    _, cell = np.unique(keys, axis=0, return_inverse=True)
    return _balls_by_cell(pts, cell.ravel(), 0.0)
