"""Near-shortest paths fast (``algorithm="auto"``), RRT*, and the certifier we test them with.

``plan_auto``: shortest paths among convex obstacles hug the obstacles' (margin-grown)
surfaces, so a visibility graph over points sampled just outside those surfaces, searched
with Dijkstra, finds the right way round them; shortcutting and a tautening step (SLSQP on
the polyline's vertices: minimise length subject to every segment's exact clearance to every
obstacle >= margin, analytic gradients) then pull the path tight. The result is verified
with the exact check; if the tightened path failed it, the graph path is kept.

``certified_shortest_path``: the same visibility graph with many more samples, closer to the
surfaces, and no tightening: an independent, verified path whose length bounds the shortest
path from above and approaches it as samples grow. Tests hold ``plan_auto`` to within 1 % of
it.

``plan_rrt_star``: RRT* (Karaman & Frazzoli 2011) with exact edge checks, seeded; a sampling
baseline (the spec's "sampling planner"), shortened afterwards by ``encoding.shortcut``.

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
from ..status import PlanStatus
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
    o = scene.obstacles[i]
    if o.kind == "box":
        return 0.5 * float(np.min(o.upper - o.lower))
    return o.radius


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


def visibility_graph_path(scene: Scene, start, goal, samples: int, rel_offset: float,
                          margin: float | None = None, rng: np.random.Generator | None = None,
                          chunk: int = 250_000) -> tuple[np.ndarray | None, int]:
    """Shortest path ``(n, 3)`` in the visibility graph of start, goal and ``samples``
    points per obstacle at distance ``margin + rel_offset * size`` from it (size = radius,
    or half the smallest side of a box). Edges are exact-checked at ``margin`` (default the
    scene's margin plus the planning slack). Returns ``(path or None, number of edges)``.

    Only near-tangent edges are kept at points on smooth obstacles (spheres, capsules): a
    shortest path leaves a smooth convex obstacle along its tangent plane, so an edge whose
    angle to that plane exceeds twice the sample spacing never helps. Box samples, start and
    goal keep all their edges.
    """
    margin = scene.safety_margin + planning_slack(scene) if margin is None else margin
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    pts, nrm = [start[None], goal[None]], [np.zeros((2, 3))]
    tol = min(1.0, 2.0 * math.sqrt(4 * math.pi / samples))
    for i in range(len(scene.obstacles)):
        off = margin + rel_offset * _obstacle_size(scene, i)
        P = scene.surface_points(i, samples, off, rng)
        pts.append(P)
        nrm.append(_normals(scene, i, P))
    X, N = np.vstack(pts), np.vstack(nrm)
    keep = scene.in_bounds(X)
    if scene.obstacles:
        keep &= scene.point_clearance(X).min(axis=1) >= margin
    keep[:2] = True
    X, N = X[keep], N[keep]
    n = len(X)
    I, J = np.triu_indices(n, 1)
    rows, cols, w = [], [], []
    for s in range(0, len(I), chunk):
        i, j = I[s:s + chunk], J[s:s + chunk]
        d = X[j] - X[i]
        L = np.linalg.norm(d, axis=1)
        u = d / np.where(L > 0, L, 1.0)[:, None]
        tangent = (np.abs(np.sum(u * N[i], axis=1)) <= tol) & \
            (np.abs(np.sum(u * N[j], axis=1)) <= tol) & (L > 0)
        i, j, L = i[tangent], j[tangent], L[tangent]
        if scene.obstacles and len(i):
            ok = scene.min_segment_clearance(X[i], X[j]) >= margin
            i, j, L = i[ok], j[ok], L[ok]
        rows.append(i)
        cols.append(j)
        w.append(L)
    rows, cols, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    G = coo_matrix((w, (rows, cols)), shape=(n, n)).tocsr()
    dist, pred = dijkstra(G, directed=False, indices=0, return_predecessors=True)
    if not np.isfinite(dist[1]):
        return None, len(w)
    order, k = [], 1
    while k >= 0:
        order.append(k)
        k = pred[k]
    return X[order[::-1]], len(w)


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
    sizes = np.array([_obstacle_size(scene, i) for i in range(len(scene.obstacles))])
    c = scene.segment_clearance(path[:-1], path[1:])
    touch = np.any(c - margin < 0.05 * sizes[None, :], axis=1)
    out = [path[:1]]
    for a, b, t in zip(path[:-1], path[1:], touch):
        out.append(np.vstack([0.5 * (a + b), b]) if t else b[None])
    return np.vstack(out)


def _slsqp(scene: Scene, P: np.ndarray, margin: float, max_iterations: int) -> np.ndarray:
    """SLSQP on the interior vertices of ``P (n, 3)``: minimise length subject to the
    clearance of each (segment, obstacle) pair near each other at the start >= margin."""
    a, b = P[0], P[-1]
    n_int = len(P) - 2
    n_obs = len(scene.obstacles)

    def full(z: np.ndarray) -> np.ndarray:
        return np.vstack([a, z.reshape(n_int, 3), b])

    def length(z):
        d = np.diff(full(z), axis=0)
        L = np.linalg.norm(d, axis=1)
        u = d / np.maximum(L, 1e-12)[:, None]
        return L.sum(), (u[:-1] - u[1:]).ravel()  # d/dp_i of |p_i - p_i-1| + |p_i+1 - p_i|

    # Only pairs near each other at the start are constrained: vertices move locally, and
    # the exact check afterwards catches anything else.
    sizes = np.array([_obstacle_size(scene, i) for i in range(n_obs)])
    c0 = scene.segment_clearance(P[:-1], P[1:])
    seg, obs = np.nonzero(c0 - margin < 2.0 * sizes[None, :])
    if len(seg) == 0:
        return P
    r = np.arange(len(seg))

    def cons(z):
        Q = full(z)
        return scene.segment_clearance(Q[seg], Q[seg + 1])[r, obs] - margin

    def cons_jac(z):
        Q = full(z)
        _, t, nrm = scene.segment_clearance(Q[seg], Q[seg + 1], details=True)
        t, nrm = t[r, obs], nrm[r, obs]
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
              params: dict | None = None, progress: ProgressFn | None = None) -> RawPlan:
    """The ``auto`` planner. ``params``: ``samples`` per obstacle (default 150),
    ``rel_offset`` (0.02), tightening ``rounds`` (1)."""
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
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    t0 = time.perf_counter()
    straight = np.vstack([start, goal])
    if scene.path_is_clear(straight):
        return RawPlan(straight, np.array([_length(straight)]), 1, {"method": "straight"})
    path, edges = visibility_graph_path(scene, start, goal, samples, rel_offset, rng=rng)
    if progress is not None:
        progress(0.5)
    if path is None:
        return RawPlan(None, np.empty(0), edges, {
            "message": "auto: no clear path in the visibility graph: start and goal may be "
                       "separated by obstacles"}, PlanStatus.NO_PATH)
    graph_len = _length(path)
    path = shortcut(scene, path)
    path = tighten(scene, path, rounds=rounds)
    path = shortcut(scene, path)
    if progress is not None:
        progress(1.0)
    return RawPlan(path, np.array([graph_len, _length(path)]), edges,
                   {"method": "visibility graph + tightening", "graph_length": graph_len,
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
    start, goal = np.asarray(start, float), np.asarray(goal, float)

    def clear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        if not scene.obstacles:
            return np.ones(len(a), dtype=bool)
        return scene.min_segment_clearance(a, b) >= margin

    cap = n_samples + 1
    X = np.empty((cap, 3))
    parent = np.full(cap, -1)
    cost = np.zeros(cap)
    children: list[list[int]] = [[]]
    X[0] = start
    n = 1
    best_cost, best_node = math.inf, -1
    goal_links: list[int] = []
    history: list[float] = []
    t0 = time.perf_counter()
    for it in range(n_samples):
        x_rand = goal if rng.random() < goal_bias else rng.uniform(scene.lower, scene.upper)
        d = np.linalg.norm(X[:n] - x_rand, axis=1)
        near_i = int(np.argmin(d))
        x_new = x_rand if d[near_i] <= step else X[near_i] + (x_rand - X[near_i]) * (
            step / d[near_i])
        if d[near_i] == 0 or not clear(X[near_i][None], x_new[None])[0]:
            continue
        r = min(step, gamma * (math.log(n + 1) / (n + 1)) ** (1 / 3))
        dn = np.linalg.norm(X[:n] - x_new, axis=1)
        near = np.nonzero(dn <= max(r, dn[near_i]))[0]
        ok = clear(X[near], np.broadcast_to(x_new, (len(near), 3)))
        near, dnear = near[ok], dn[near][ok]
        via = cost[near] + dnear
        k = int(np.argmin(via))
        X[n], parent[n], cost[n] = x_new, near[k], via[k]
        children.append([])
        children[near[k]].append(n)
        new = n
        n += 1
        # Rewire: neighbours reached more cheaply through the new node.
        better = cost[new] + dnear < cost[near]
        for j, dj in zip(near[better], dnear[better]):
            children[parent[j]].remove(j)
            parent[j] = new
            children[new].append(j)
            delta = cost[new] + dj - cost[j]
            stack = [j]
            while stack:  # the whole subtree gets cheaper by delta
                m = stack.pop()
                cost[m] += delta
                stack.extend(children[m])
        dg = float(np.linalg.norm(goal - x_new))
        if dg <= step and clear(x_new[None], goal[None])[0]:
            goal_links.append(new)
        if goal_links:
            gl = np.array(goal_links)
            tot = cost[gl] + np.linalg.norm(X[gl] - goal, axis=1)
            best_node = int(gl[np.argmin(tot)])
            best_cost = float(tot.min())
        if it % 100 == 99:
            history.append(best_cost)
            if progress is not None:
                progress((it + 1) / n_samples)
        if time_limit is not None and time.perf_counter() - t0 > float(time_limit):
            break
    history.append(best_cost)
    if best_node < 0:
        return RawPlan(None, np.array(history), n, {
            "message": f"rrt_star: no path to the goal after {n} tree nodes"},
            PlanStatus.BUDGET_SPENT)
    chain, k = [], best_node
    while k >= 0:
        chain.append(X[k])
        k = parent[k]
    path = np.vstack([np.array(chain[::-1]), goal])
    return RawPlan(path, np.array(history), n, {"tree_nodes": n})
