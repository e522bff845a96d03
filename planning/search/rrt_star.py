"""RRT* (Karaman and Frazzoli, IJRR 2011) in two forms.

``rrt_star``: over a space with batch distances and segment tests. Each iteration draws
``rng.random()`` for the goal bias and, unless the goal is taken, ``space.sample(rng)``;
the nearest node steps at most ``step`` towards the sample; the new
node joins, among its neighbours within the shrinking radius ``min(step, gamma (log n /
n)^(1/dim))`` whose edge to it is free (one batch test), the one giving the cheapest path
from the start, and the neighbours reached more cheaply through it are rewired (their
subtrees' costs lowered). A node within ``step`` of the goal that sees it links to it; the
best link so far is the answer. The tool paths' planner (``planning.paths.auto``) runs it
in the scene's box.

``rrt_star_informed``: in a box with weighted lengths, several goals, one segment test at a
time (the cheapest candidate parent first) and informed sampling once a path is known;
joint-space motion (``planning.motion.search.rrt_star``) runs it. The two keep their own
parent choice and draws (a batch test of every neighbour is cheap for tool points, a
sequential one for an arm's exact collision checks), which their seeded answers depend on.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from ..status import PlanStatus
from .result import SearchResult, Stop
from .shortcut import path_length

__all__ = ["rrt_star", "rrt_star_informed"]


def rrt_star(space, start: np.ndarray, goal: np.ndarray, rng: np.random.Generator, *,
             samples: int, step: float, goal_bias: float, gamma: float,
             time_limit: float | None = None,
             progress: Callable[[float], None] | None = None) -> SearchResult:
    """The best path from ``start (dim,)`` to ``goal (dim,)`` after ``samples`` iterations
    (or ``time_limit`` s), module docstring. ``space``: ``sample(rng)``, ``distances(X,
    x)``, ``distance(a, b)`` and ``segments_free(A, B)`` (``BoxSpace`` has them).
    ``history``: the best cost every 100 iterations and at the end; ``stats["tree_nodes"]``;
    status ``budget_spent`` when no node linked to the goal. ``progress(fraction)`` every
    100 iterations (it may raise to stop)."""
    start, goal = np.asarray(start, float), np.asarray(goal, float)
    dim = len(start)
    clear = space.segments_free
    cap = samples + 1
    X = np.empty((cap, dim))
    parent = np.full(cap, -1)
    cost = np.zeros(cap)
    children: list[list[int]] = [[]]
    X[0] = start
    n = 1
    best_cost, best_node = math.inf, -1
    goal_links: list[int] = []
    history: list[float] = []
    t0 = time.perf_counter()
    for it in range(samples):
        x_rand = goal if rng.random() < goal_bias else space.sample(rng)
        d = space.distances(X[:n], x_rand)
        near_i = int(np.argmin(d))
        x_new = x_rand if d[near_i] <= step else X[near_i] + (x_rand - X[near_i]) * (
            step / d[near_i])
        if d[near_i] == 0 or not clear(X[near_i][None], x_new[None])[0]:
            continue
        r = min(step, gamma * (math.log(n + 1) / (n + 1)) ** (1 / dim))
        dn = space.distances(X[:n], x_new)
        near = np.nonzero(dn <= max(r, dn[near_i]))[0]
        ok = clear(X[near], np.broadcast_to(x_new, (len(near), dim)))
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
        dg = space.distance(goal, x_new)
        if dg <= step and clear(x_new[None], goal[None])[0]:
            goal_links.append(new)
        if goal_links:
            gl = np.array(goal_links)
            tot = cost[gl] + space.distances(X[gl], goal)
            best_node = int(gl[np.argmin(tot)])
            best_cost = float(tot.min())
        if it % 100 == 99:
            history.append(best_cost)
            if progress is not None:
                progress((it + 1) / samples)
        if time_limit is not None and time.perf_counter() - t0 > float(time_limit):
            break
    history.append(best_cost)
    stats = {"tree_nodes": n}
    if best_node < 0:
        return SearchResult(None, PlanStatus.BUDGET_SPENT, stats, np.array(history))
    chain, k = [], best_node
    while k >= 0:
        chain.append(X[k])
        k = parent[k]
    path = np.vstack([np.array(chain[::-1]), goal])
    return SearchResult(path, PlanStatus.OK, stats, np.array(history))


# ---- informed RRT* in a weighted box (joint space) ---------------------------------------------
def rrt_star_informed(space, start: np.ndarray, goals: np.ndarray, rng: np.random.Generator,
                      stop: Stop, *, initial: np.ndarray | None = None,
                      on_improve: Callable[[float], None] | None = None) -> SearchResult:
    """The shortest path from ``start (dim,)`` to one of ``goals (G, dim)`` RRT* finds
    before ``stop()``, in the box ``[space.lower, space.upper]`` with lengths weighted by
    ``space.weights``; None (``budget_spent``) if it reaches no goal.

    A node joins the neighbour within the shrinking radius that gives it the shortest path
    from the start (neighbours tried in order of that cost, each edge checked by
    ``space.segment_free`` until one is free) and then rewires its neighbours through
    itself; once a goal is reached, samples are drawn from the ellipsoid of configurations
    that could shorten the best path (Gammell et al.'s informed sampling, IROS 2014), else
    by ``space.sample``; steps by ``space.steer`` (at most ``space.step``). ``initial``: a
    known path whose length bounds the informed samples; ``on_improve(cost)`` at each better
    path. ``stats``: ``iterations``, ``nodes``, ``improvements``."""
    start = np.asarray(start, dtype=float)
    goals = np.atleast_2d(np.asarray(goals, dtype=float))
    w, step = space.weights, space.step
    lo, hi = space.lower, space.upper
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
            x = space.sample(rng)
        d = ((X[:n] - x) * w)
        d2 = np.einsum("ij,ij->i", d, d)
        i = int(np.argmin(d2))
        new, _ = space.steer(X[i], x)
        if not space.segment_free(X[i], new):
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
            if space.segment_free(X[k], new):
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
            if c < cost[k] - 1e-12 and space.segment_free(new, X[k]):
                delta = cost[k] - c
                parent[k], cost[k] = me, c
                _lower_subtree(parent, cost, n, int(k), delta)
        # Reach a goal from the new node.
        dg = np.sqrt((((goal_w - new * w)) ** 2).sum(1))
        for gi in np.argsort(dg):
            if c_new + dg[gi] >= best_cost or dg[gi] > step:
                break
            if space.segment_free(new, goals[gi]):
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
    status = PlanStatus.BUDGET_SPENT if best_path is None else PlanStatus.OK
    return SearchResult(best_path, status, stats)


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


