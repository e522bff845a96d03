"""Near-shortest paths fast (``algorithm="auto"``), RRT*, and the certifier we test them with.

``plan_auto``: shortest paths among convex obstacles hug the obstacles' (margin-grown)
surfaces, so a visibility graph over points sampled just outside those surfaces, searched
with Dijkstra, finds the right way round them; shortcutting and a tautening step (SLSQP on
the polyline's vertices: minimise length subject to every nearby segment's exact clearance
to its obstacle >= margin, analytic gradients) then pull the path tight. The result is
verified with the exact check; if the tightened path failed it, the graph path is kept.

It scales with the obstacles that matter, not with all of them:

* samples buried inside other obstacles are dropped, and every clearance check goes through
  the scene's broad phase (``planning.paths.broadphase``): a segment meets only the
  obstacles whose bounding spheres it passes near;
* a path no longer than ``c`` stays inside the ellipsoid of points ``x`` with
  ``|x - start| + |x - goal| <= c``, and an edge ``i–j`` can lie on it only if
  ``|start - x_i| + |x_i - x_j| + |x_j - goal| <= c``. When the samples outnumber
  ``max_nodes``, the search runs in rounds: a bound ``c`` growing from 1 % over the
  straight line (fourfold each time) until a path is found, then ``c`` = the best length
  found, each round on the samples inside its ellipsoid, thinned evenly (one per voxel) to
  ``max_nodes``, and on the edges the bound allows;
* every array is sized by the inputs and the caps (``max_nodes``, ``RAW_SAMPLES_PER_NODE``,
  ``PAIR_CHUNK``): memory stays bounded whatever the number of obstacles;
* past ``time_limit`` CPU seconds, or when the thinned graph finds nothing, RRT* (below)
  gets the time left (``extra["method"]`` says so); a graph that was complete and found
  nothing is an honest ``no_path``.

``certified_shortest_path``: the same visibility graph with many more samples, closer to the
surfaces, and no tightening: an independent, verified path whose length bounds the shortest
path from above and approaches it as samples grow. Tests hold ``plan_auto`` to within 1 % of
it.

``plan_rrt_star``: RRT* (Karaman & Frazzoli 2011, ``planning.search.rrt_star`` in the scene's
box) with exact edge checks, seeded; a sampling baseline (the spec's "sampling planner"),
shortened afterwards by ``encoding.shortcut``.

Lengths in mm; points ``(3,)``; paths ``(n, 3)``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from kinematics.errors import FieldError

from ..budget import ProgressFn
from ..search import BoxSpace, rrt_star
from ..status import PlanStatus
from .broadphase import BlockedGrid
from .encoding import planning_slack, shortcut
from .scene import Scene

__all__ = ["RawPlan", "visibility_graph_path", "certified_shortest_path", "tighten",
           "plan_auto", "plan_rrt_star"]


@dataclass(frozen=True)
class RawPlan:
    """A planner's path before ``plan_path`` verifies and shortens it (None if none, and
    ``status`` then says why: ``no_path`` or ``budget_spent``)."""

    path: np.ndarray | None
    history: np.ndarray
    evaluations: int
    extra: dict = field(default_factory=dict)
    status: PlanStatus = PlanStatus.OK


def _obstacle_size(scene: Scene, i: int) -> float:
    return float(scene.obstacle_sizes()[i])


def _normals(scene: Scene, i: int, X: np.ndarray) -> np.ndarray:
    """Outward unit normals ``(n, 3)`` at points near obstacle ``i``'s surface (zero for
    boxes, whose edges and corners have no single normal)."""
    o = scene.obstacles[i]
    if o.kind == "sphere":
        d = X - o.center
    elif o.kind == "capsule":
        ax = o.b - o.a
        t = np.clip((X - o.a) @ ax / max(float(ax @ ax), 1e-300), 0.0, 1.0)
        d = X - (o.a + t[:, None] * ax)
    else:
        return np.zeros_like(X)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


#: Most graph nodes one round of ``plan_auto`` searches (the pairs grow as its square).
DEFAULT_MAX_NODES = 1200
#: Most surface samples drawn over all obstacles per graph node allowed: per-obstacle
#: samples shrink to fit (the samples are thinned to the nodes anyway).
RAW_SAMPLES_PER_NODE = 40
#: Fewest surface samples per obstacle, whatever the number of obstacles.
MIN_SAMPLES = 12
#: CPU seconds of one ``plan_auto`` call: the graph search gets 60 %, the sampling fallback
#: the rest.
DEFAULT_TIME_LIMIT = 8.0
#: Node pairs examined per vectorised step of the graph's construction.
PAIR_CHUNK = 1 << 19
#: Bounds of the rounds until a path is found: these fractions over the straight line,
#: then none.
EXCESS_STEPS = (0.01, 0.1, 1.0)
#: A refinement round follows only if the new ellipsoid holds at most this fraction of the
#: samples the last round saw.
REFINE_SHRINK = 0.7
#: Samples of the RRT* fallback (its time limit usually ends it first).
FALLBACK_SAMPLES = 20_000
#: Most rounds of one ``plan_auto`` call.
MAX_ROUNDS = 8


class _Deadline:
    """A budget of CPU seconds of the calling thread (``time.thread_time``): ``left()``
    seconds, ``spent`` once they are gone. CPU time, not wall time: on a loaded machine the
    same input gets the same work before the budget ends."""

    def __init__(self, seconds: float | None) -> None:
        self.end = math.inf if seconds is None else time.thread_time() + float(seconds)

    def left(self) -> float:
        return self.end - time.thread_time()

    @property
    def spent(self) -> bool:
        return self.left() <= 0


@dataclass(frozen=True)
class _Samples:
    """Free surface samples: points ``X (K, 3)``, outward normals ``N (K, 3)`` (zero where
    there is no single normal: boxes, start, goal), the angle between neighbouring samples
    of the same obstacle ``spacing (K,)`` (rad), the offset surface's radius of curvature
    ``radius (K,)`` (mm; inf where flat), the obstacle sampled ``owner (K,)`` and the
    radius ``core (K,)`` of a ball inside it centred ``radius`` behind the sample along
    ``-N`` (0: none, boxes)."""

    X: np.ndarray
    N: np.ndarray
    spacing: np.ndarray
    radius: np.ndarray
    owner: np.ndarray
    core: np.ndarray


def _rotations(rng: np.random.Generator | None, n: int) -> np.ndarray:
    """``n`` rotations ``(n, 3, 3)``: random from ``rng``, identity without it."""
    if rng is None:
        return np.broadcast_to(np.eye(3), (n, 3, 3))
    Q, _ = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    return Q


def _surface_samples(scene: Scene, per: int, rel_offset: float, margin: float,
                     rng: np.random.Generator | None) -> _Samples:
    """``per`` samples around each obstacle at ``margin + rel_offset * size`` from it,
    without those out of bounds or closer than ``margin`` to another obstacle."""
    n = len(scene.obstacles)
    Q = _rotations(rng, n)
    a = scene._arrays
    X = np.empty((n, per, 3))
    N = np.zeros((n, per, 3))
    radius = np.full((n, per), np.inf)
    core = np.zeros((n, per))
    sph = a["sphere_index"]
    if len(sph):  # all spheres at once: the lattice turned by each sphere's rotation
        u = np.einsum("kj,nij->nki", _fibonacci_lattice(per), Q[sph])
        R = a["sr"] * (1.0 + rel_offset) + margin
        X[sph] = a["sc"][:, None, :] + R[:, None, None] * u
        N[sph] = u
        radius[sph] = R[:, None]
        core[sph] = a["sr"][:, None]
    for i in np.setdiff1d(np.arange(n), sph):
        off = margin + rel_offset * _obstacle_size(scene, int(i))
        X[i] = scene.surface_points(int(i), per, off, rotation=Q[i])
        N[i] = _normals(scene, int(i), X[i])
        if scene.obstacles[i].kind == "capsule":
            radius[i] = scene.obstacles[i].radius + off
            core[i] = scene.obstacles[i].radius
    X, N, radius = X.reshape(-1, 3), N.reshape(-1, 3), radius.reshape(-1)
    owner = np.repeat(np.arange(n), per)
    keep = scene.in_bounds(X)
    keep[keep] = scene.segments_clear(X[keep], X[keep], margin)
    spacing = np.full(int(keep.sum()), math.sqrt(4 * math.pi / per))
    return _Samples(X[keep], N[keep], spacing, radius[keep], owner[keep],
                    core.reshape(-1)[keep])


def _fibonacci_lattice(n: int) -> np.ndarray:
    """``n`` nearly evenly spread unit vectors ``(n, 3)`` (the scene's lattice)."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    r = np.sqrt(np.maximum(0.0, 1 - z * z))
    phi = k * math.pi * (3 - math.sqrt(5))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _thin(X: np.ndarray, max_nodes: int) -> tuple[np.ndarray, float]:
    """Indices of at most ``max_nodes`` of the points ``X (K, 3)``, one per cube of a grid
    (the first in each), and the grid's edge (0 when nothing was dropped)."""
    if len(X) <= max_nodes:
        return np.arange(len(X)), 0.0
    lo = X.min(axis=0)
    extent = max(float(np.max(X.max(axis=0) - lo)), 1e-9)

    def cells(h: float) -> np.ndarray:
        ijk = np.floor((X - lo) / h).astype(np.int64)
        m = int(ijk.max()) + 1
        return np.unique((ijk[:, 0] * m + ijk[:, 1]) * m + ijk[:, 2], return_index=True)[1]

    # Samples lie on surfaces: their count per grid falls as 1 / h^2. Aim at 90 % of the cap.
    h = extent / math.sqrt(max_nodes)
    for _ in range(12):
        first = cells(h)
        if 0.7 * max_nodes <= len(first) <= max_nodes:
            break
        h *= min(4.0, max(0.25, math.sqrt(len(first) / (0.9 * max_nodes))))
    while len(first) > max_nodes:
        h *= 1.1
        first = cells(h)
    return np.sort(first), h


def _graph_path(scene: Scene, X: np.ndarray, N: np.ndarray, tol: np.ndarray, bound: float,
                margin: float, deadline: _Deadline, grid: BlockedGrid | None = None,
                owner: np.ndarray | None = None, core: np.ndarray | None = None,
                radius: np.ndarray | None = None) -> tuple[np.ndarray | None, int, bool]:
    """Shortest path from ``X[0]`` to ``X[1]`` through the nodes ``X (K, 3)``: every pair
    whose direction makes ``|u . N_i| <= tol_i`` at both ends (near-tangent; zero normals
    pass), that a path no longer than ``bound`` could use, and that is clear by ``margin``.

    Before the exact check against every obstacle, cheap tests reject most pairs through
    obstacles, each one sound (it rejects only pairs the exact check would): the ball of
    radius ``core_i`` centred ``radius_i`` behind node ``i`` along ``-N_i`` lies inside the
    obstacle it was sampled from (spheres, capsules); nodes without one (``core`` 0) are
    checked against that obstacle itself (``owner (K,)``, -1: none); then ``grid``'s
    blocked cells. Returns ``(path or None, edges, finished)``; ``finished`` is False when
    ``deadline`` ended the construction."""
    K = len(X)
    h_start = np.linalg.norm(X - X[0], axis=1)
    h_goal = np.linalg.norm(X - X[1], axis=1)
    rows_per_step = max(1, PAIR_CHUNK // max(K, 1))
    rows, cols, w = [], [], []
    cols_all = np.arange(K)
    for a in range(0, K - 1, rows_per_step):
        if deadline.spent:
            return None, int(sum(len(x) for x in w)), False
        i = np.arange(a, min(a + rows_per_step, K - 1))
        d = X[None, :, :] - X[i, None, :]  # (B, K, 3)
        L = np.linalg.norm(d, axis=2)
        ok = (cols_all[None, :] > i[:, None]) & (L > 0)
        via = np.minimum(h_start[i, None] + h_goal[None, :], h_start[None, :] + h_goal[i, None])
        ok &= via + L <= bound
        dot_i = np.einsum("bkj,bj->bk", d, N[i])
        dot_j = np.einsum("bkj,kj->bk", d, N)
        ok &= (np.abs(dot_i) <= tol[i, None] * L) & (np.abs(dot_j) <= tol[None, :] * L)
        bi, bj = np.nonzero(ok)
        ei, ej, el = i[bi], bj, L[bi, bj]
        if core is not None and len(ei):
            keep = np.ones(len(ei), dtype=bool)
            for node, s in ((ei, -dot_i[bi, bj]), (ej, dot_j[bi, bj])):
                # Distance from the node's inner ball centre to the pair's segment.
                R, r = radius[node], core[node]
                s = np.where(r > 0, R, 0.0) * s
                t = np.clip(s / (el * el), 0.0, 1.0)
                dist2 = np.where(r > 0, R, 0.0) ** 2 - 2 * t * s + t * t * el * el
                keep &= ~((r > 0) & (dist2 < (r + margin) ** 2))
            ei, ej, el = ei[keep], ej[keep], el[keep]
        if owner is not None and len(ei):
            for side in (0, 1):
                node = ei if side == 0 else ej
                o = owner[node]
                has = np.nonzero((o >= 0) & ((core[node] <= 0) if core is not None else True))[0]
                if not len(has):
                    continue
                bad = has[scene.pair_clearance(X[ei[has]], X[ej[has]], o[has]) < margin]
                ok_e = np.ones(len(ei), dtype=bool)
                ok_e[bad] = False
                ei, ej, el = ei[ok_e], ej[ok_e], el[ok_e]
        if grid is not None and len(ei):
            free = ~grid.hits(X[ei], X[ej])
            ei, ej, el = ei[free], ej[free], el[free]
        if len(ei) and scene.obstacles:
            clear = scene.segments_clear(X[ei], X[ej], margin)
            ei, ej, el = ei[clear], ej[clear], el[clear]
        rows.append(ei)
        cols.append(ej)
        w.append(el)
    rows_a = np.concatenate(rows) if rows else np.empty(0, dtype=int)
    cols_a = np.concatenate(cols) if cols else np.empty(0, dtype=int)
    w_a = np.concatenate(w) if w else np.empty(0)
    G = coo_matrix((w_a, (rows_a, cols_a)), shape=(K, K)).tocsr()
    dist, pred = dijkstra(G, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return None, len(w_a), True
    order, k = [], 1
    while k >= 0:
        order.append(k)
        k = pred[k]
    return X[order[::-1]], len(w_a), True


#: Cells of the blocked grid one round of ``plan_auto`` builds.
GRID_CELLS = 1 << 20


def _frame(start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Orthonormal axes ``(3, 3)`` (rows), the first from ``start`` to ``goal``."""
    e1 = goal - start
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(e1, [1.0, 0.0, 0.0] if abs(e1[0]) < 0.9 else [0.0, 1.0, 0.0])
    e2 /= np.linalg.norm(e2)
    return np.array([e1, e2, np.cross(e1, e2)])


def _grid(scene: Scene, start: np.ndarray, goal: np.ndarray, bound: float,
          margin: float) -> BlockedGrid:
    """The blocked grid over the ellipsoid of paths no longer than ``bound`` (its bounding
    box in the start–goal frame), or over the scene's bounds when ``bound`` is inf."""
    axes = _frame(start, goal)
    d = float(np.linalg.norm(goal - start))
    if math.isfinite(bound):
        half_width = 0.5 * math.sqrt(max(bound * bound - d * d, 0.0))
        lo = np.array([-(bound - d) / 2, -half_width, -half_width])
        hi = np.array([d + (bound - d) / 2, half_width, half_width])
    else:
        corners = np.array([[x, y, z] for x in (scene.lower[0], scene.upper[0])
                            for y in (scene.lower[1], scene.upper[1])
                            for z in (scene.lower[2], scene.upper[2])])
        local = (corners - start) @ axes.T
        lo, hi = local.min(axis=0), local.max(axis=0)
    return BlockedGrid(scene, start + lo @ axes, axes, hi - lo, margin, GRID_CELLS)


def visibility_graph_path(scene: Scene, start, goal, samples: int, rel_offset: float,
                          margin: float | None = None, rng: np.random.Generator | None = None,
                          ) -> tuple[np.ndarray | None, int]:
    """Shortest path ``(n, 3)`` in the visibility graph of start, goal and ``samples``
    points per obstacle at distance ``margin + rel_offset * size`` from it (size = radius,
    or half the smallest side of a box). Edges are exact-checked at ``margin`` (default the
    scene's margin plus the planning slack). Returns ``(path or None, number of edges)``.

    Only near-tangent edges are kept at points on smooth obstacles (spheres, capsules): a
    shortest path leaves a smooth convex obstacle along its tangent plane, so an edge whose
    angle to that plane exceeds twice the sample spacing never helps. Box samples, start and
    goal keep all their edges. Every node pair is examined: ``plan_auto`` is the one that
    scales.
    """
    margin = scene.safety_margin + planning_slack(scene) if margin is None else margin
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    S = _surface_samples(scene, samples, rel_offset, margin, rng)
    X = np.vstack([start, goal, S.X])
    N = np.vstack([np.zeros((2, 3)), S.N])
    tol = np.full(len(X), min(1.0, 2.0 * math.sqrt(4 * math.pi / samples)))
    path, edges, _ = _graph_path(scene, X, N, tol, math.inf, margin, _Deadline(None))
    return path, edges


def certified_shortest_path(scene: Scene, start, goal, samples: int = 800,
                            rel_offset: float = 0.004) -> np.ndarray | None:
    """A fine visibility-graph path (verified at the scene's margin) to certify others by.

    Its length is an upper bound on the shortest path; the bound tightens as ``samples``
    grows and ``rel_offset`` shrinks (chords between neighbouring samples must clear the
    obstacle they lie on, which sets how close to the surface the samples may be).
    """
    path, _ = visibility_graph_path(scene, start, goal, samples, rel_offset,
                                    margin=scene.safety_margin)
    if path is None or not scene.path_is_clear(path):
        return None
    return path


def _refine(scene: Scene, path: np.ndarray, margin: float) -> np.ndarray:
    """Insert the midpoint of every segment that touches an obstacle (clearance within 5 %
    of the obstacle's size of ``margin``): the polyline then follows the curved surface."""
    sizes = scene.obstacle_sizes()
    seg, obs, c = scene.near_pairs(path[:-1], path[1:], margin + 0.05 * float(sizes.max()))
    touch = np.zeros(len(path) - 1, dtype=bool)
    touch[seg[c - margin < 0.05 * sizes[obs]]] = True
    out = [path[:1]]
    for a, b, t in zip(path[:-1], path[1:], touch):
        out.append(np.vstack([0.5 * (a + b), b]) if t else b[None])
    return np.vstack(out)


def _slsqp(scene: Scene, P: np.ndarray, margin: float, max_iterations: int) -> np.ndarray:
    """SLSQP on the interior vertices of ``P (n, 3)``: minimise length subject to the
    clearance of each (segment, obstacle) pair near each other at the start >= margin."""
    a, b = P[0], P[-1]
    n_int = len(P) - 2

    def full(z: np.ndarray) -> np.ndarray:
        return np.vstack([a, z.reshape(n_int, 3), b])

    def length(z):
        d = np.diff(full(z), axis=0)
        L = np.linalg.norm(d, axis=1)
        u = d / np.maximum(L, 1e-12)[:, None]
        return L.sum(), (u[:-1] - u[1:]).ravel()  # d/dp_i of |p_i - p_i-1| + |p_i+1 - p_i|

    # Only pairs near each other at the start are constrained: vertices move locally, and
    # the exact check afterwards catches anything else.
    sizes = scene.obstacle_sizes()
    seg, obs, c0 = scene.near_pairs(P[:-1], P[1:], margin + 2.0 * float(sizes.max()))
    near = c0 - margin < 2.0 * sizes[obs]
    seg, obs = seg[near], obs[near]
    if len(seg) == 0:
        return P
    r = np.arange(len(seg))

    def cons(z):
        Q = full(z)
        return scene.pair_clearance(Q[seg], Q[seg + 1], obs) - margin

    def cons_jac(z):
        Q = full(z)
        _, t, nrm = scene.pair_clearance(Q[seg], Q[seg + 1], obs, details=True)
        Jc = np.zeros((len(seg), n_int + 2, 3))
        Jc[r, seg] = (1 - t)[:, None] * nrm
        Jc[r, seg + 1] = t[:, None] * nrm
        return Jc[:, 1:-1].reshape(len(seg), n_int * 3)

    # No bounds passed to SLSQP (they slow it down badly): the result is clipped into them,
    # and the exact check decides.
    res = minimize(length, P[1:-1].ravel(), jac=True, method="SLSQP",
                   constraints=[{"type": "ineq", "fun": cons, "jac": cons_jac}],
                   options={"maxiter": max_iterations, "ftol": 1e-9 * scene.diagonal})
    return np.clip(full(res.x), scene.lower, scene.upper)


def tighten(scene: Scene, path, margin: float | None = None, rounds: int = 3,
            max_iterations: int = 100) -> np.ndarray:
    """Pull a clear path ``(n, 3)`` taut in ``rounds``: SLSQP on the interior vertices
    (length subject to every nearby segment–obstacle clearance ``>= margin``, default margin
    + slack, and the bounds), then split the segments that touch an obstacle and repeat.
    Each round's result is kept only if it passes the exact check at the scene's margin and
    is shorter."""
    path = np.asarray(path, dtype=float)
    if len(path) <= 2 or not scene.obstacles:
        return path
    margin = scene.safety_margin + planning_slack(scene) if margin is None else margin
    best = path
    for k in range(rounds):
        P = best if k == 0 else _refine(scene, best, margin)
        try:
            Q = _slsqp(scene, P, margin, max_iterations)
        except (ValueError, np.linalg.LinAlgError):
            break
        if scene.path_is_clear(Q) and _length(Q) < _length(best):
            best = Q
    return best


def _length(path: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


def plan_auto(scene: Scene, start, goal, rng: np.random.Generator, *,
              params: dict | None = None, progress: ProgressFn | None = None,
              max_nodes: int = DEFAULT_MAX_NODES,
              time_limit: float | None = DEFAULT_TIME_LIMIT,
              fallback_samples: int = FALLBACK_SAMPLES) -> RawPlan:
    """The ``auto`` planner. ``params``: ``samples`` per obstacle (default 150; fewer when
    the obstacles are so many that ``RAW_SAMPLES_PER_NODE * max_nodes`` would be passed,
    never below ``MIN_SAMPLES``), ``rel_offset`` (0.02), tightening ``rounds`` (1).

    ``max_nodes``: most graph nodes per round (more samples are thinned evenly);
    ``time_limit`` (CPU seconds of the calling thread, None: no limit): the graph search
    gets 60 % of it, the RRT* fallback (at most ``fallback_samples`` samples) the rest.
    ``extra["method"]`` names what gave the path: ``straight``, ``visibility graph +
    tightening`` or ``rrt_star fallback + tightening``; ``extra["rounds"]`` lists each
    round's bound (mm, inf: none), nodes and path length (None: no path)."""
    params = dict(params or {})
    samples = int(params.pop("samples", 150))
    rel_offset = float(params.pop("rel_offset", 0.02))
    rounds = int(params.pop("rounds", 1))
    if params:
        name = sorted(params)[0]
        raise FieldError(("params", name), f"params.{name} is not a parameter of auto; "
                         "known: rel_offset, rounds, samples")
    for name, bad in (("samples", samples < 4), ("rounds", rounds < 0),
                      ("rel_offset", not rel_offset > 0)):
        if bad:
            raise FieldError(("params", name), "params: samples must be >= 4, rounds >= 0, "
                             "rel_offset > 0")
    if max_nodes < 16:
        raise ValueError(f"max_nodes must be at least 16, got {max_nodes}")
    if time_limit is not None and not time_limit > 0:
        raise ValueError(f"time_limit must be positive or None, got {time_limit}")
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    t0, cpu0 = time.perf_counter(), time.thread_time()
    straight = np.vstack([start, goal])
    if scene.path_is_clear(straight):
        return RawPlan(straight, np.array([_length(straight)]), 1, {"method": "straight"})
    margin = scene.safety_margin + planning_slack(scene)
    graph_deadline = _Deadline(None if time_limit is None else 0.6 * time_limit)
    per = max(MIN_SAMPLES, min(samples, RAW_SAMPLES_PER_NODE * max_nodes
                                   // max(1, len(scene.obstacles))))
    S = _surface_samples(scene, per, rel_offset, margin, rng)
    s_dist = np.linalg.norm(S.X - start, axis=1) + np.linalg.norm(S.X - goal, axis=1)
    complete = len(S.X) + 2 <= max_nodes  # one round over every sample, as a plain graph
    d = float(np.linalg.norm(goal - start))
    bounds = [math.inf] if complete else [d * (1 + e) for e in EXCESS_STEPS] + [math.inf]
    bound = bounds.pop(0)
    best, best_len, graph_len = None, math.inf, math.inf
    thinned, timed_out, edges_total = False, False, 0
    log: list[dict] = []
    for k in range(MAX_ROUNDS):
        idx = np.nonzero(s_dist <= bound)[0]
        inside = len(idx)
        keep, h = _thin(S.X[idx], max_nodes - 2)
        idx = idx[keep]
        thinned |= h > 0
        # Thinned nodes sit farther apart than the lattice: the tangent test widens with it.
        spacing = np.maximum(S.spacing[idx], h / S.radius[idx])
        tol = np.concatenate([[1.0, 1.0], np.minimum(1.0, 2.0 * spacing)])
        X = np.vstack([start, goal, S.X[idx]])
        N = np.vstack([np.zeros((2, 3)), S.N[idx]])
        grid = _grid(scene, start, goal, bound, margin) if scene.broad_phase else None
        owner = np.concatenate([[-1, -1], S.owner[idx]])
        core = np.concatenate([[0.0, 0.0], S.core[idx]])
        radius = np.concatenate([[0.0, 0.0], S.radius[idx]])
        path, edges, finished = _graph_path(scene, X, N, tol, bound, margin, graph_deadline,
                                            grid, owner, core, radius)
        edges_total += edges
        entry = {"bound": bound, "nodes": len(X), "length": None}
        log.append(entry)
        if not finished:
            timed_out = True
            break
        if path is None:
            if best is not None or not bounds:
                break  # a refinement found nothing better, or no bound is left to try
            bound = bounds.pop(0)  # no path this short through these nodes: a looser bound
        else:
            glen = _length(path)
            path = shortcut(scene, path)
            path = tighten(scene, path, rounds=rounds)
            path = shortcut(scene, path)
            entry["length"] = L = _length(path)
            gain = best_len - L
            if L < best_len:
                best, best_len, graph_len = path, L, glen
            # Another round, inside the ellipsoid of this graph path, helps only if this
            # round's nodes were thinned, it improved, and that ellipsoid holds markedly
            # fewer samples than this round saw (its nodes then sit closer together).
            if h == 0 or not gain > 1e-4 * best_len or glen >= bound or \
                    np.count_nonzero(s_dist <= glen) > REFINE_SHRINK * inside:
                break
            bound = glen
        if progress is not None:
            progress(min(0.9, (k + 1) / MAX_ROUNDS))
        if graph_deadline.spent:
            timed_out = True
            break
    extra = {"graph_length": graph_len, "rounds": log, "samples_per_obstacle": per,
             "free_samples": len(S.X)}
    if best is not None:
        if progress is not None:
            progress(1.0)
        return RawPlan(best, np.array([graph_len, best_len]), edges_total, extra | {
            "method": "visibility graph + tightening", "seconds": time.perf_counter() - t0})
    if not (thinned or timed_out):
        return RawPlan(None, np.empty(0), edges_total, extra | {
            "message": "auto: no clear path in the visibility graph: start and goal may be "
                       "separated by obstacles"}, PlanStatus.NO_PATH)
    # The graph was thinned or stopped by the clock: a sampling planner gets the time left.
    left = None if time_limit is None else max(0.05 * time_limit,
                                               time_limit - (time.thread_time() - cpu0))
    fallback = plan_rrt_star(scene, start, goal, rng,
                             params={"samples": fallback_samples, "time_limit": left})
    extra["fallback_nodes"] = fallback.evaluations
    why = "the time limit" if timed_out else "thinned graphs found no path"
    if fallback.path is None:
        return RawPlan(None, np.empty(0), edges_total + fallback.evaluations, extra | {
            "method": "rrt_star fallback", "message": f"auto: {why}, and the rrt_star "
            f"fallback found no path in {fallback.evaluations} tree nodes"},
            PlanStatus.BUDGET_SPENT)
    raw_len = _length(fallback.path)
    path = shortcut(scene, fallback.path)
    path = tighten(scene, path, rounds=rounds)
    path = shortcut(scene, path)
    if progress is not None:
        progress(1.0)
    return RawPlan(path, np.array([raw_len, _length(path)]),
                   edges_total + fallback.evaluations, extra | {
                       "method": "rrt_star fallback + tightening", "fallback_reason": why,
                       "seconds": time.perf_counter() - t0})


def plan_rrt_star(scene: Scene, start, goal, rng: np.random.Generator, *,
                  params: dict | None = None, progress: ProgressFn | None = None) -> RawPlan:
    """RRT* with exact edge checks. ``params``: ``samples`` (default 3000), ``step`` (max
    edge, default 1/10 of the scene diagonal), ``goal_bias`` (0.05), ``gamma`` (rewiring
    radius constant, default 2 * diagonal), ``time_limit`` s (None)."""
    params = dict(params or {})
    n_samples = int(params.pop("samples", 3000))
    step = float(params.pop("step", 0.1 * scene.diagonal))
    goal_bias = float(params.pop("goal_bias", 0.05))
    gamma = float(params.pop("gamma", 2.0 * scene.diagonal))
    time_limit = params.pop("time_limit", None)
    if params:
        name = sorted(params)[0]
        raise FieldError(("params", name), f"params.{name} is not a parameter of rrt_star; "
                         "known: gamma, goal_bias, samples, step, time_limit")
    for name, bad in (("samples", n_samples < 1), ("step", not step > 0),
                      ("goal_bias", not 0 <= goal_bias <= 1), ("gamma", not gamma > 0)):
        if bad:
            raise FieldError(("params", name), "params: samples >= 1, step > 0, "
                             "0 <= goal_bias <= 1, gamma > 0")
    margin = scene.safety_margin + planning_slack(scene)
    space = BoxSpace(scene.lower, scene.upper, step,
                     lambda a, b: scene.segments_clear(a, b, margin))
    res = rrt_star(space, start, goal, rng, samples=n_samples, step=step, goal_bias=goal_bias,
                   gamma=gamma, time_limit=time_limit, progress=progress)
    n = res.stats["tree_nodes"]
    if res.path is None:
        return RawPlan(None, res.history, n, {
            "message": f"rrt_star: no path to the goal after {n} tree nodes"},
            PlanStatus.BUDGET_SPENT)
    return RawPlan(res.path, res.history, n, {"tree_nodes": n})
