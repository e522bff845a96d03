"""Sampling-based searches in a robot's joint space, over a ``MotionChecker``.

* ``rrt_connect``: Kuffner and LaValle's RRT-Connect (ICRA 2000): a tree from the start and
  one from the goals (every goal configuration is a root of the second), each iteration
  extending one tree a step of at most ``step`` towards a uniform sample and then greedily
  connecting the other tree to the new node, the trees swapping roles every iteration.
* ``rrt_star``: Karaman and Frazzoli's RRT* (IJRR 2011), asymptotically optimal: a node joins
  the neighbour within the shrinking radius that gives it the shortest path from the start and
  then rewires its neighbours through itself; once a goal is reached, samples are drawn from
  the ellipsoid of configurations that could shorten the best path (Gammell et al.'s informed
  sampling, IROS 2014). It runs until its time budget ends, keeping the best path found.
* ``shortcut``: path simplification: random shortcuts between points anywhere along the
  path (not only waypoints), then the removal of waypoints whose neighbours see each other.
* ``rrt_connect_compiled`` and ``shortcut_compiled``: the same, compiled
  (``planning.motion._rrt``), on the sphere model alone or settling flagged states exactly;
  ``escape``: a short exactly checked path from a start or goal the spheres flag to one they
  clear, so that the search on the spheres alone can run between them.

All work in the checker's weighted joint coordinates (prismatic millimetres scaled by
``PRISMATIC_SCALE``); every edge a search keeps is checked by ``MotionChecker.segment_free``
at the given ``resolution``. Randomness comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .checker import MotionChecker, _kernels

__all__ = ["Tree", "rrt_connect", "rrt_star", "shortcut", "path_length", "DEFAULT_STEP"]

#: Longest edge a search adds in one extension (weighted joint-space units, rad).
DEFAULT_STEP = 1.5

Stop = Callable[[], bool]


def path_length(path: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Sum of the Euclidean lengths of the segments of ``path (K, dof)`` (weighted)."""
    if len(path) < 2:
        return 0.0
    d = np.diff(path, axis=0)
    if weights is not None:
        d = d * weights
    return float(np.sqrt((d * d).sum(1)).sum())


class Tree:
    """Nodes ``(n, dof)`` with parents (-1 for a root), grown by doubling. A node can be
    dropped with its subtree (``kill``); ``checked[i]`` says whether the edge to its parent
    was checked at the fine resolution."""

    def __init__(self, roots: np.ndarray, capacity: int = 1024) -> None:
        roots = np.atleast_2d(roots)
        cap = max(capacity, 2 * len(roots))
        self.X = np.empty((cap, roots.shape[1]))
        self.parent = np.empty(cap, dtype=np.int64)
        self.alive = np.zeros(cap, dtype=bool)
        self.checked = np.zeros(cap, dtype=bool)
        self.n = len(roots)
        self.X[:self.n] = roots
        self.parent[:self.n] = -1
        self.alive[:self.n] = True
        self.checked[:self.n] = True

    def add(self, x: np.ndarray, parent: int, checked: bool = False) -> int:
        if self.n == len(self.X):
            self.X = np.concatenate([self.X, np.empty_like(self.X)])
            self.parent = np.concatenate([self.parent, np.empty_like(self.parent)])
            self.alive = np.concatenate([self.alive, np.zeros_like(self.alive)])
            self.checked = np.concatenate([self.checked, np.zeros_like(self.checked)])
        self.X[self.n] = x
        self.parent[self.n] = parent
        self.alive[self.n] = True
        self.checked[self.n] = checked
        self.n += 1
        return self.n - 1

    def nearest(self, x: np.ndarray, w: np.ndarray) -> int:
        k = _kernels()
        if k is not None:
            return int(k.nearest(self.X, self.n, self.alive, x, w))
        d = (self.X[:self.n] - x) * w
        d2 = np.einsum("ij,ij->i", d, d)
        d2[~self.alive[:self.n]] = np.inf
        return int(np.argmin(d2))

    def branch(self, i: int) -> list[int]:
        """Node indices from node ``i`` up to its root."""
        out = []
        while i >= 0:
            out.append(i)
            i = int(self.parent[i])
        return out

    def kill(self, i: int) -> None:
        """Drop node ``i`` and every node below it."""
        dead = np.zeros(self.n, dtype=bool)
        dead[i] = True
        par = self.parent[:self.n]
        # Children always come after their parents: one pass in index order.
        for k in range(i + 1, self.n):
            if par[k] >= 0 and dead[par[k]]:
                dead[k] = True
        self.alive[:self.n] &= ~dead


def _steer(a: np.ndarray, b: np.ndarray, w: np.ndarray, step: float) -> tuple[np.ndarray, bool]:
    d = float(np.sqrt((((b - a) * w) ** 2).sum()))
    if d <= step:
        return b, True
    return a + (b - a) * (step / d), False


def _sample(rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return lo + (hi - lo) * rng.random(len(lo))


def rrt_connect(checker: MotionChecker, start: np.ndarray, goals: np.ndarray,
                rng: np.random.Generator, stop: Stop, resolution: float,
                step: float | None = None, lazy: float | None = None
                ) -> tuple[np.ndarray | None, dict]:
    """A path ``(K, dof)`` from ``start`` to one of ``goals (G, dof)`` (all free), or None
    when ``stop()`` says so first; and statistics.

    Edges enter the trees checked at the coarser ``lazy`` step (default
    ``LAZY_RESOLUTION``, never finer than ``resolution``); when the trees meet, the edges of
    the path between them are checked at ``resolution``, and an edge that fails drops the
    nodes below it from its tree and the search goes on. The path returned is free at
    ``resolution``."""
    w = checker.weights
    lo, hi = checker.lower, checker.upper
    step = DEFAULT_STEP if step is None else step
    coarse = max(resolution, LAZY_RESOLUTION if lazy is None else lazy)
    stats = {"iterations": 0, "nodes": 0, "lazy_failures": 0}
    for g in goals:
        if checker.segment_free(start, g, resolution):
            stats["nodes"] = 1 + len(goals)
            return np.stack([start, g]), stats
    ta, tb = Tree(start), Tree(goals)
    a_is_start = True
    while not stop():
        stats["iterations"] += 1
        x = _sample(rng, lo, hi)
        i = ta.nearest(x, w)
        new, _ = _steer(ta.X[i], x, w, step)
        if checker.segment_free(ta.X[i], new, coarse):
            k = ta.add(new, i, coarse <= resolution)
            # Connect the other tree greedily towards the new node.
            j = tb.nearest(new, w)
            met = False
            while True:
                nxt, reached = _steer(tb.X[j], new, w, step)
                if not checker.segment_free(tb.X[j], nxt, coarse):
                    break
                j = tb.add(nxt, j, coarse <= resolution)
                if reached:
                    met = True
                    break
            if met:
                path = _validated(checker, ta, k, tb, j, a_is_start, resolution, stats)
                if path is not None:
                    stats["nodes"] = ta.n + tb.n
                    return path, stats
        ta, tb = tb, ta
        a_is_start = not a_is_start
    stats["nodes"] = ta.n + tb.n
    return None, stats


#: Joint step (rad) at which RRT-Connect checks the edges it adds (``rrt_connect``).
LAZY_RESOLUTION = 0.1


def _validated(checker: MotionChecker, ta: Tree, k: int, tb: Tree, j: int, a_is_start: bool,
               resolution: float, stats: dict) -> np.ndarray | None:
    """The path through node ``k`` of ``ta`` and node ``j`` of ``tb`` (the same
    configuration), start first, once every edge is checked at ``resolution``; None if one
    fails (the nodes below it are dropped)."""
    for tree, leaf in ((ta, k), (tb, j)):
        for i in tree.branch(leaf):
            p = int(tree.parent[i])
            if p < 0 or tree.checked[i]:
                continue
            if not checker.segment_free(tree.X[p], tree.X[i], resolution):
                tree.kill(i)
                stats["lazy_failures"] += 1
                return None
            tree.checked[i] = True
    up_a = [ta.X[i] for i in ta.branch(k)]
    up_b = [tb.X[i] for i in tb.branch(j)[1:]]
    nodes = up_a[::-1] + up_b if a_is_start else up_b[::-1] + up_a
    return np.array(nodes)


# ---- simplification -------------------------------------------------------------------------
def _reduce(checker: MotionChecker, path: np.ndarray, resolution: float) -> np.ndarray:
    """Drop waypoints: from each kept waypoint, jump to the farthest later one in sight."""
    if len(path) <= 2:
        return path
    keep = [0]
    i = 0
    n = len(path)
    while i < n - 1:
        j = n - 1
        while j > i + 1 and not checker.segment_free(path[i], path[j], resolution):
            j -= 1
        keep.append(j)
        i = j
    return path[keep]


def _point_at(path: np.ndarray, cum: np.ndarray, s: float) -> tuple[int, np.ndarray]:
    """The segment index and the point at arc length ``s`` of the path."""
    i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(path) - 2))
    seg = cum[i + 1] - cum[i]
    t = 0.0 if seg <= 0 else (s - cum[i]) / seg
    return i, path[i] + (path[i + 1] - path[i]) * min(max(t, 0.0), 1.0)


def shortcut(checker: MotionChecker, path: np.ndarray, rng: np.random.Generator, stop: Stop,
             resolution: float, attempts: int = 100, patience: int = 25) -> np.ndarray:
    """A shorter path with the same ends (see the module docstring): at most ``attempts``
    random shortcuts, ending after ``patience`` failures in a row or when ``stop()``."""
    w = checker.weights
    path = _reduce(checker, np.asarray(path, dtype=float), resolution)
    fails = 0
    for _ in range(attempts):
        if len(path) <= 2 or fails >= patience or stop():
            break
        seg = np.sqrt((((np.diff(path, axis=0)) * w) ** 2).sum(1))
        cum = np.r_[0.0, np.cumsum(seg)]
        total = cum[-1]
        s0, s1 = np.sort(rng.random(2) * total)
        i, a = _point_at(path, cum, s0)
        j, b = _point_at(path, cum, s1)
        if j <= i:
            fails += 1
            continue
        old = (cum[i + 1] - s0) + (s1 - cum[j]) + (cum[j] - cum[i + 1])
        new = float(np.sqrt((((b - a) * w) ** 2).sum()))
        # The new segment, and the pieces of the old ones it keeps (checked at states of
        # their own, which the whole segments never checked).
        if new >= old - 1e-9 or not checker.segment_free(a, b, resolution) \
                or not checker.segment_free(path[i], a, resolution) \
                or not checker.segment_free(b, path[j + 1], resolution):
            fails += 1
            continue
        path = np.concatenate([path[:i + 1], a[None], b[None], path[j + 1:]])
        # Points that coincide with their neighbours add nothing.
        keep = np.r_[True, np.any(np.abs(np.diff(path, axis=0)) > 1e-12, axis=1)]
        path = path[keep]
        fails = 0
    return _reduce(checker, path, resolution)


# ---- RRT* -------------------------------------------------------------------------------------
def rrt_star(checker: MotionChecker, start: np.ndarray, goals: np.ndarray,
             rng: np.random.Generator, stop: Stop, resolution: float,
             step: float = DEFAULT_STEP, initial: np.ndarray | None = None,
             on_improve: Callable[[float], None] | None = None
             ) -> tuple[np.ndarray | None, dict]:
    """The shortest path RRT* finds before ``stop()`` (module docstring), None if it
    reaches no goal; ``initial``: a known path whose length bounds the informed samples."""
    w = checker.weights
    lo, hi = checker.lower, checker.upper
    dof = len(start)
    X = np.empty((4096, dof))
    parent = np.empty(4096, dtype=np.int64)
    cost = np.empty(4096)
    X[0], parent[0], cost[0] = start, -1, 0.0
    n = 1
    best_cost = math.inf
    best_path = None
    if initial is not None:
        best_path = np.asarray(initial, dtype=float)
        best_cost = path_length(best_path, w)
    goal_w = goals * w
    gamma = 2.0 * (1 + 1.0 / dof) ** (1.0 / dof) * float(
        np.prod((hi - lo) * w) ** (1.0 / dof))
    stats = {"iterations": 0, "nodes": 0, "improvements": 0}
    goal_nodes: list[tuple[int, int]] = []
    while not stop():
        stats["iterations"] += 1
        x = _informed(rng, start, goals, best_cost, lo, hi, w)
        if x is None:
            x = _sample(rng, lo, hi)
        d = ((X[:n] - x) * w)
        d2 = np.einsum("ij,ij->i", d, d)
        i = int(np.argmin(d2))
        new, _ = _steer(X[i], x, w, step)
        if not checker.segment_free(X[i], new, resolution):
            continue
        radius = min(step, gamma * (math.log(n + 1) / (n + 1)) ** (1.0 / dof))
        dn = np.sqrt(np.einsum("ij,ij->i", (X[:n] - new) * w, (X[:n] - new) * w))
        near = np.flatnonzero(dn <= max(radius, 1e-12))
        via = cost[near] + dn[near]
        order = near[np.argsort(via)]
        chosen = i
        c_new = cost[i] + float(dn[i])
        for k in order:
            if cost[k] + dn[k] >= c_new - 1e-12:
                break
            if checker.segment_free(X[k], new, resolution):
                chosen, c_new = int(k), float(cost[k] + dn[k])
                break
        if n == len(X):
            X = np.concatenate([X, np.empty_like(X)])
            parent = np.concatenate([parent, np.empty_like(parent)])
            cost = np.concatenate([cost, np.empty_like(cost)])
        X[n], parent[n], cost[n] = new, chosen, c_new
        me = n
        n += 1
        # Rewire the neighbours through the new node.
        for k in near:
            c = c_new + float(dn[k])
            if c < cost[k] - 1e-12 and checker.segment_free(new, X[k], resolution):
                delta = cost[k] - c
                parent[k], cost[k] = me, c
                _lower_subtree(parent, cost, n, int(k), delta)
        # Reach a goal from the new node.
        dg = np.sqrt((((goal_w - new * w)) ** 2).sum(1))
        for gi in np.argsort(dg):
            if c_new + dg[gi] >= best_cost or dg[gi] > step:
                break
            if checker.segment_free(new, goals[gi], resolution):
                goal_nodes.append((me, int(gi)))
                break
        for node, gi in goal_nodes:
            c = cost[node] + float(np.sqrt((((goals[gi] - X[node]) * w) ** 2).sum()))
            if c < best_cost - 1e-9:
                best_cost = c
                chain = []
                k = node
                while k >= 0:
                    chain.append(X[k])
                    k = int(parent[k])
                best_path = np.array(chain[::-1] + [goals[gi]])
                stats["improvements"] += 1
                if on_improve is not None:
                    on_improve(best_cost)
    stats["nodes"] = n
    return best_path, stats


def _lower_subtree(parent: np.ndarray, cost: np.ndarray, n: int, root: int, delta: float
                   ) -> None:
    """Lower the cost of every descendant of ``root`` by ``delta``."""
    stack = [root]
    kids = None
    while stack:
        k = stack.pop()
        if kids is None:
            kids = {}
            for c in range(n):
                kids.setdefault(int(parent[c]), []).append(c)
        for c in kids.get(k, ()):
            cost[c] -= delta
            stack.append(c)


def _informed(rng: np.random.Generator, start: np.ndarray, goals: np.ndarray, best: float,
              lo: np.ndarray, hi: np.ndarray, w: np.ndarray, tries: int = 32
              ) -> np.ndarray | None:
    """A uniform sample of the prolate hyperspheroid of points whose start-to-goal detour
    is shorter than ``best`` (for the goal nearest the start), within the limits; None when
    there is no bound yet or no sample landed inside the limits."""
    if not math.isfinite(best):
        return None
    a, b = start * w, goals[0] * w
    c_min = float(np.linalg.norm(b - a))
    if best <= c_min:
        return None
    dof = len(a)
    centre = 0.5 * (a + b)
    e1 = (b - a) / c_min if c_min > 0 else np.eye(dof)[0]
    # Rotation taking the first axis to e1 (Householder).
    u = np.eye(dof)[0] - e1
    nu = float(np.linalg.norm(u))
    r1 = 0.5 * best
    r = 0.5 * math.sqrt(max(best * best - c_min * c_min, 0.0))
    for _ in range(tries):
        x = rng.normal(size=dof)
        x *= rng.random() ** (1.0 / dof) / np.linalg.norm(x)
        x[0] *= r1
        x[1:] *= r
        if nu > 1e-12:
            x = x - 2.0 * u * (u @ x) / (nu * nu)
        y = (centre + x) / w
        if np.all(y >= lo) and np.all(y <= hi):
            return y
    return None


# ---- compiled searches (sphere model) -----------------------------------------------------------
#: Iterations of the compiled RRT-Connect before its first restart, and the growth of that
#: budget at each restart.
RESTART_ITERATIONS = 2048
RESTART_GROWTH = 1.5

def _compiled(checker: MotionChecker):
    """The compiled searches for ``checker``, or None (no numba, or no chain layout)."""
    if checker._k is None:
        return None
    import planning.motion._rrt as _rrt

    work = checker.__dict__.get("_work")
    if work is None:
        work = _rrt.make_work(checker._robot, checker._scene,
                              np.ascontiguousarray(checker.step_weights))
        checker._work = work
    # The checker's deadline, for the compiled segment checks of this thread.
    mode = work[-1]
    mode[2] = 0 if checker.deadline is None else 1
    mode[3] = 0
    _rrt._local.deadline = checker.deadline
    return _rrt, work


def sphere_free(checker: MotionChecker, Q: np.ndarray) -> np.ndarray:
    """``(B,)`` whether the sphere model alone clears each configuration."""
    exact, zone = checker.exact, checker.exact_zone
    checker.exact, checker.exact_zone = False, None
    try:
        return np.atleast_1d(checker.free(Q))
    finally:
        checker.exact, checker.exact_zone = exact, zone


def rrt_connect_compiled(checker: MotionChecker, start: np.ndarray, goals: np.ndarray,
                        rng: np.random.Generator, stop: Stop, resolution: float,
                         exact: bool = False, step: float | None = None,
                         lazy: float | None = None, chunk: int = 256,
                         restart: int = RESTART_ITERATIONS) -> tuple[np.ndarray | None, dict]:
    """``rrt_connect`` compiled: on the sphere model alone (a flagged state is a collision;
    start and goals must be sphere-free), or with ``exact`` confirming flagged states on
    the exact shapes (``checker.exact`` must be on). The search starts afresh after
    ``restart`` iterations without a path, each time with ``RESTART_GROWTH`` times the
    budget (0: never). None when ``stop()`` says so first or there are no compiled
    kernels."""
    got = _compiled(checker)
    if got is None:
        return None, {"compiled": False}
    rr, work = got
    dof = checker.dof
    step = DEFAULT_STEP if step is None else step
    coarse = max(resolution, LAZY_RESOLUTION if lazy is None else lazy)
    cap = 8192
    X = np.empty((2, cap, dof))
    P = np.full((2, cap), -1, dtype=np.int64)
    A = np.zeros((2, cap), dtype=bool)
    K = np.zeros((2, cap), dtype=bool)
    X[0, 0] = start
    X[1, :len(goals)] = goals
    A[0, 0] = True
    A[1, :len(goals)] = True
    K[:, :max(1, len(goals))] = True
    N = np.array([1, len(goals)], dtype=np.int64)
    side = np.zeros(1, dtype=np.int64)
    state = np.array([int(rng.integers(1, 2**63 - 1))], dtype=np.uint64)
    out = np.empty((2 * cap, dof))
    lo = np.ascontiguousarray(checker.lower, dtype=float)
    hi = np.ascontiguousarray(checker.upper, dtype=float)
    w = np.ascontiguousarray(checker.weights)
    count, mode = work[-2], work[-1]
    mode[0] = 1 if exact else 0
    rr._local.checker = checker
    stats = {"iterations": 0, "nodes": 0, "compiled": True, "restarts": 0}
    budget, used = restart, 0
    while not stop():
        if restart and used >= budget:
            # Heavy-tailed run times: start afresh with a larger budget.
            N[:] = (1, len(goals))
            side[0] = 0
            used = 0
            budget = int(budget * RESTART_GROWTH)
            stats["restarts"] += 1
        used += chunk
        c0 = int(count[0])
        code, m = rr.rrt_connect_run(checker._robot, checker._scene, X, P, A, K, N, side,
                                     lo, hi, w, float(step), float(coarse), float(resolution),
                                     checker.margin, chunk, state, work, out)
        checker.checks += int(count[0]) - c0
        stats["iterations"] += chunk
        if code == rr.RUN_FOUND:
            stats["nodes"] = int(N.sum())
            return out[:m].copy(), stats
        if code == rr.RUN_FULL:
            if cap >= 1 << 20:
                break
            grow = cap
            X = np.concatenate([X, np.empty((2, grow, dof))], axis=1)
            P = np.concatenate([P, np.full((2, grow), -1, dtype=np.int64)], axis=1)
            A = np.concatenate([A, np.zeros((2, grow), dtype=bool)], axis=1)
            K = np.concatenate([K, np.zeros((2, grow), dtype=bool)], axis=1)
            cap *= 2
            out = np.empty((2 * cap, dof))
    stats["nodes"] = int(N.sum())
    return None, stats


def shortcut_compiled(checker: MotionChecker, path: np.ndarray, rng: np.random.Generator,
                      resolution: float, attempts: int = 100, patience: int = 30,
                      exact: bool = False) -> np.ndarray:
    """``shortcut`` compiled: on the sphere model alone (the path must be sphere-free at
    ``resolution``), or with ``exact`` confirming flagged states on the exact shapes; the
    path as it is without compiled kernels."""
    got = _compiled(checker)
    if got is None or len(path) <= 2:
        return path
    rr, work = got
    n = len(path)
    buf = np.empty((n + 2 * attempts + 4, checker.dof))
    buf[:n] = path
    w = np.ascontiguousarray(checker.weights)
    state = np.array([int(rng.integers(1, 2**63 - 1))], dtype=np.uint64)
    count, mode = work[-2], work[-1]
    mode[0] = 1 if exact else 0
    rr._local.checker = checker
    c0 = int(count[0])
    n = rr.reduce_path(checker._robot, checker._scene, buf, n, w, float(resolution),
                       checker.margin, work)
    n = rr.shortcut_run(checker._robot, checker._scene, buf, n, w, float(resolution),
                        checker.margin, int(attempts), int(patience), state, work)
    n = rr.reduce_path(checker._robot, checker._scene, buf, n, w, float(resolution),
                       checker.margin, work)
    checker.checks += int(count[0]) - c0
    return buf[:n].copy()



#: How far (weighted rad) ``escape`` looks for a configuration the spheres clear, with how
#: many extensions of which length.
ESCAPE_RADIUS = 0.5
ESCAPE_TRIES = 150
ESCAPE_STEP = 0.1


def escape(checker: MotionChecker, q: np.ndarray, rng: np.random.Generator, stop: Stop,
           resolution: float) -> np.ndarray | None:
    """A short path ``(K, dof)`` from ``q`` (free, but flagged by the spheres: a gripper
    about an object) to a configuration the sphere model clears, every segment checked on
    the exact shapes at ``resolution`` (``checker.exact`` must be on): a small random tree
    grown from ``q`` by steps of ``ESCAPE_STEP`` towards samples within ``ESCAPE_RADIUS``.
    None if ``ESCAPE_TRIES`` extensions find none."""
    w = checker.weights
    tree = Tree(q)
    lo = np.maximum(checker.lower, q - ESCAPE_RADIUS / w)
    hi = np.minimum(checker.upper, q + ESCAPE_RADIUS / w)
    for _ in range(ESCAPE_TRIES):
        if stop():
            return None
        x = _sample(rng, lo, hi)
        i = tree.nearest(x, w)
        new, _ = _steer(tree.X[i], x, w, ESCAPE_STEP)
        if not checker.segment_free(tree.X[i], new, resolution, ends=True):
            continue
        k = tree.add(new, i, True)
        if sphere_free(checker, new[None])[0]:
            return np.array([tree.X[j] for j in tree.branch(k)][::-1])
    return None
