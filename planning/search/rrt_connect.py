"""RRT-Connect (Kuffner and LaValle, ICRA 2000) over any ``SearchSpace``.

A tree from the starts and one from the goals (every goal is a root of the second); each
iteration extends one tree one step towards a sample (``space.sample``) and then greedily
connects the other tree to the new node, step after step from its nearest node, until it
gets there or is blocked; the trees swap roles every iteration, whatever happened.

The order of the random draws is the space's: one ``space.sample(rng)`` per iteration and
nothing else, so a space and a seed fix the search. With ``lazy``, edges enter the trees
checked by ``space.coarse_free``; when the trees meet, the edges of the path between them
are checked by ``space.segment_free``, an edge that fails drops the nodes below it from its
tree and the search goes on. ``direct`` first tries the straight segment from the start to
each goal.

The joint-space motion planner runs the same algorithm compiled (``planning.motion._rrt``,
its twin over the sphere model); the drilling arms (``planning.drilling.rrt``) and the
Python joint-space search (``planning.motion.search``) run this one.
"""

from __future__ import annotations

import numpy as np

from ..status import PlanStatus
from .result import SearchResult, Stop
from .space import SearchSpace
from .tree import Tree

__all__ = ["rrt_connect"]


def rrt_connect(space: SearchSpace, start: np.ndarray, goals: np.ndarray,
                rng: np.random.Generator, stop: Stop, *, lazy: bool = False,
                direct: bool = False) -> SearchResult:
    """A path from ``start (dim,)`` to one of ``goals (G, dim)`` (module docstring), start
    first, or None with status ``budget_spent`` when ``stop()`` ends the search first.

    ``stats``: ``iterations`` run, ``nodes`` of both trees, ``lazy_failures`` (edges a
    found path lost when checked finely). The start and the goals are taken as free."""
    start = np.asarray(start, dtype=float)
    goals = np.atleast_2d(np.asarray(goals, dtype=float))
    stats = {"iterations": 0, "nodes": 0, "lazy_failures": 0}
    if direct:
        for g in goals:
            if space.segment_free(start, g):
                stats["nodes"] = 1 + len(goals)
                return SearchResult(np.stack([start, g]), PlanStatus.OK, stats)
    ta, tb = Tree(start), Tree(goals)
    a_is_start = True
    extend_free = space.coarse_free if lazy else space.segment_free
    while not stop():
        stats["iterations"] += 1
        x = space.sample(rng)
        k = _extend(space, ta, x, extend_free, lazy)
        if k is not None:
            j = _connect(space, tb, ta.X[k], extend_free, lazy)
            if j is not None:
                path = _validated(space, ta, k, tb, j, a_is_start, stats)
                if path is not None:
                    stats["nodes"] = ta.n + tb.n
                    return SearchResult(path, PlanStatus.OK, stats)
        ta, tb = tb, ta
        a_is_start = not a_is_start
    stats["nodes"] = ta.n + tb.n
    return SearchResult(None, PlanStatus.BUDGET_SPENT, stats)


def _extend(space: SearchSpace, tree: Tree, x: np.ndarray, free, lazy: bool) -> int | None:
    """One step of ``tree`` from its node nearest ``x`` towards ``x``: the new node (or the
    nearest node itself when it coincides with ``x``), None when the edge is blocked."""
    i = space.nearest(tree, x)
    new, _ = space.steer(tree.X[i], x)
    if new is None:
        return i
    if not free(tree.X[i], new):
        return None
    return tree.add(new, i, not lazy)


def _connect(space: SearchSpace, tree: Tree, target: np.ndarray, free, lazy: bool
             ) -> int | None:
    """Steps of ``tree`` from its node nearest ``target`` until it gets there (the node
    reaching it) or is blocked (None)."""
    j = space.nearest(tree, target)
    while True:
        nxt, reached = space.steer(tree.X[j], target)
        if nxt is None:
            return j
        if not free(tree.X[j], nxt):
            return None
        j = tree.add(nxt, j, not lazy)
        if reached:
            return j


def _validated(space: SearchSpace, ta: Tree, k: int, tb: Tree, j: int, a_is_start: bool,
               stats: dict) -> np.ndarray | None:
    """The path through node ``k`` of ``ta`` and node ``j`` of ``tb`` (where they meet),
    start first, once every edge is checked by ``space.segment_free``; None if one fails
    (the nodes below it are dropped). The meeting configuration is the start tree's."""
    for tree, leaf in ((ta, k), (tb, j)):
        for i in tree.branch(leaf):
            p = int(tree.parent[i])
            if p < 0 or tree.checked[i]:
                continue
            if not space.segment_free(tree.X[p], tree.X[i]):
                tree.kill(i)
                stats["lazy_failures"] += 1
                return None
            tree.checked[i] = True
    (ts, s), (tg, g) = ((ta, k), (tb, j)) if a_is_start else ((tb, j), (ta, k))
    up_s = [ts.X[i] for i in ts.branch(s)]
    up_g = [tg.X[i] for i in tg.branch(g)[1:]]
    return np.array(up_s[::-1] + up_g)
