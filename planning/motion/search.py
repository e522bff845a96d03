"""Sampling-based searches in a robot's joint space, over a ``MotionChecker``.

* ``rrt_connect``: Kuffner and LaValle's RRT-Connect (ICRA 2000), ``planning.search``'s, lazy,
  over the checker's weighted joint space: a tree from the start and one from the goals
  (every goal configuration is a root of the second), each iteration extending one tree a
  step of at most ``step`` towards a uniform sample and then greedily connecting the other
  tree to the new node, the trees swapping roles every iteration.
* ``rrt_star``: Karaman and Frazzoli's RRT* (IJRR 2011), asymptotically optimal: a node joins
  the neighbour within the shrinking radius that gives it the shortest path from the start and
  then rewires its neighbours through itself; once a goal is reached, samples are drawn from
  the ellipsoid of configurations that could shorten the best path (Gammell et al.'s informed
  sampling, IROS 2014). It runs until its time budget ends, keeping the best path found.
* ``shortcut``: path simplification (``planning.search.shortcut``): random shortcuts between
  points anywhere along the path (not only waypoints), then the removal of waypoints whose
  neighbours see each other.
* ``rrt_connect_compiled`` and ``shortcut_compiled``: the same, compiled
  (``planning.motion._rrt``, the compiled twin of the core's RRT-Connect and shortcutting),
  on the sphere model alone or settling flagged states exactly;
  ``escape``: a short exactly checked path from a start or goal the spheres flag to one they
  clear, so that the search on the spheres alone can run between them.

All work in the checker's weighted joint coordinates (prismatic millimetres scaled by
``PRISMATIC_SCALE``); every edge a search keeps is checked by ``MotionChecker.segment_free``
at the given ``resolution``. Randomness comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..search import Tree as _CoreTree
from ..search import path_length, rrt_star_informed
from ..search import rrt_connect as _rrt_connect
from ..search import shortcut as _shortcut
from .checker import MotionChecker, _kernels

__all__ = ["Tree", "rrt_connect", "rrt_star", "shortcut", "path_length", "DEFAULT_STEP"]

#: Longest edge a search adds in one extension (weighted joint-space units, rad).
DEFAULT_STEP = 1.5

Stop = Callable[[], bool]


class Tree(_CoreTree):
    """``planning.search.Tree`` with the nearest node in weighted joint coordinates
    (compiled when the kernels are there)."""

    def nearest(self, x: np.ndarray, w: np.ndarray) -> int:
        return _nearest(self, x, w)


def _nearest(tree: _CoreTree, x: np.ndarray, w: np.ndarray) -> int:
    """The live node of ``tree`` nearest ``x`` in coordinates weighted by ``w``."""
    k = _kernels()
    if k is not None:
        return int(k.nearest(tree.X, tree.n, tree.alive, x, w))
    d = (tree.X[:tree.n] - x) * w
    d2 = np.einsum("ij,ij->i", d, d)
    d2[~tree.alive[:tree.n]] = np.inf
    return int(np.argmin(d2))


class _JointSpace:
    """The checker's weighted joint space as a ``planning.search`` space: uniform samples
    within the limits, steps of at most ``step``, edges checked at ``resolution`` (and at
    ``coarse`` while a lazy search grows its trees)."""

    def __init__(self, checker: MotionChecker, resolution: float, coarse: float,
                 step: float) -> None:
        self.checker, self.resolution, self.coarse, self.step = checker, resolution, coarse, step
        self.w, self.lo, self.hi = checker.weights, checker.lower, checker.upper
        # The names RRT* (``planning.search.rrt_star_informed``) reads.
        self.weights, self.lower, self.upper = self.w, self.lo, self.hi

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return _sample(rng, self.lo, self.hi)

    def nearest(self, tree: _CoreTree, x: np.ndarray) -> int:
        return _nearest(tree, x, self.w)

    def steer(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, bool]:
        return _steer(a, b, self.w, self.step)

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        return self.checker.segment_free(a, b, self.resolution)

    def coarse_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        return self.checker.segment_free(a, b, self.coarse)


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
    step = DEFAULT_STEP if step is None else step
    coarse = max(resolution, LAZY_RESOLUTION if lazy is None else lazy)
    res = _rrt_connect(_JointSpace(checker, resolution, coarse, step), start, goals, rng, stop,
                       lazy=coarse > resolution, direct=True)
    return res.path, res.stats


#: Joint step (rad) at which RRT-Connect checks the edges it adds (``rrt_connect``).
LAZY_RESOLUTION = 0.1


# ---- simplification -------------------------------------------------------------------------
def shortcut(checker: MotionChecker, path: np.ndarray, rng: np.random.Generator, stop: Stop,
             resolution: float, attempts: int = 100, patience: int = 25) -> np.ndarray:
    """A shorter path with the same ends (``planning.search.shortcut``, in the checker's
    weighted coordinates, every segment checked at ``resolution``): at most ``attempts``
    random shortcuts, ending after ``patience`` failures in a row or when ``stop()``."""
    return _shortcut(path, lambda a, b: checker.segment_free(a, b, resolution), rng, stop,
                     attempts, patience, checker.weights)


# ---- RRT* -------------------------------------------------------------------------------------
def rrt_star(checker: MotionChecker, start: np.ndarray, goals: np.ndarray,
             rng: np.random.Generator, stop: Stop, resolution: float,
             step: float = DEFAULT_STEP, initial: np.ndarray | None = None,
             on_improve: Callable[[float], None] | None = None
             ) -> tuple[np.ndarray | None, dict]:
    """The shortest path RRT* finds before ``stop()`` (module docstring;
    ``planning.search.rrt_star_informed`` in the checker's weighted joint space, every edge
    checked at ``resolution``), None if it reaches no goal; ``initial``: a known path whose
    length bounds the informed samples."""
    res = rrt_star_informed(_JointSpace(checker, resolution, resolution, step), start, goals,
                            rng, stop, initial=initial, on_improve=on_improve)
    return res.path, res.stats


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
                         exact: bool | Callable[[], bool] = False, step: float | None = None,
                         lazy: float | None = None, chunk: int = 256,
                         restart: int = RESTART_ITERATIONS,
                         head: np.ndarray | None = None,
                         tails: Sequence[np.ndarray] = (),
                         validate: bool = True) -> tuple[np.ndarray | None, dict]:
    """``rrt_connect`` compiled: on the sphere model alone (a flagged state is a collision),
    or with ``exact`` confirming flagged states on the exact shapes (``checker.exact`` must
    be on). ``exact`` may be a callable asked before each ``chunk`` of iterations: a tree
    grown on the spheres stays valid when the exact stage joins, so one search can switch.
    ``head`` (a path from ``start``, its first row) and ``tails`` (paths ending at goals),
    their edges already checked at ``resolution`` (the way out of a state the spheres flag):
    the trees then grow from the head's last state and the tails' first states, and the
    answer is put together with them. The search starts afresh after ``restart``
    iterations without a path, each time with ``RESTART_GROWTH`` times the budget (0:
    never). Without ``validate`` the path's edges are answered checked at the lazy step
    only (the edges ``head`` and ``tails`` bring at ``resolution``), for
    ``shortcut_compiled(checked=...)``, which certifies what it keeps. Statistics:
    ``iterations``, ``nodes``, ``restarts``, ``exact_chunks``. None when ``stop()`` says so
    first or there are no compiled kernels."""
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
    head = None if head is None else np.asarray(head, dtype=float)
    tails = [np.asarray(t, dtype=float) for t in tails]
    roots = np.array([t[0] for t in tails]) if tails else goals
    X[0, 0] = start if head is None else head[-1]
    X[1, :len(roots)] = roots
    A[0, 0] = True
    A[1, :len(roots)] = True
    K[:, :max(1, len(roots))] = True
    N = np.array([1, len(roots)], dtype=np.int64)
    first_N = N.copy()
    side = np.zeros(1, dtype=np.int64)
    state = np.array([int(rng.integers(1, 2**63 - 1))], dtype=np.uint64)
    out = np.empty((2 * cap, dof))
    lo = np.ascontiguousarray(checker.lower, dtype=float)
    hi = np.ascontiguousarray(checker.upper, dtype=float)
    w = np.ascontiguousarray(checker.weights)
    count, mode = work[-2], work[-1]
    rr._local.checker = checker
    stats = {"iterations": 0, "nodes": 0, "compiled": True, "restarts": 0, "exact_chunks": 0}
    budget, used = restart, 0
    while not stop():
        if restart and used >= budget:
            # Heavy-tailed run times: start afresh with a larger budget.
            N[:] = first_N
            side[0] = 0
            used = 0
            budget = int(budget * RESTART_GROWTH)
            stats["restarts"] += 1
        used += chunk
        now_exact = bool(exact() if callable(exact) else exact)
        mode[0] = 1 if now_exact else 0
        stats["exact_chunks"] += now_exact
        c0 = int(count[0])
        code, m = rr.rrt_connect_run(checker._robot, checker._scene, X, P, A, K, N, side,
                                     lo, hi, w, float(step), float(coarse), float(resolution),
                                     checker.margin, chunk, state, work, out, validate)
        checker.checks += int(count[0]) - c0
        stats["iterations"] += chunk
        if code == rr.RUN_FOUND:
            stats["nodes"] = int(N.sum())
            path = out[:m].copy()
            if not validate:
                # The segments checked at the lazy step only: the search's own.
                first = 0 if head is None else len(head) - 1
                stats["lazy_segments"] = [first, first + m - 1]
                stats["lazy_step"] = coarse
            if head is not None:
                path = np.concatenate([head[:-1], path])
            if tails:
                tail = next(t for t in tails if np.array_equal(t[0], path[-1]))
                path = np.concatenate([path, tail[1:]])
            return path, stats
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


#: The compiled shortcuts first check their new segments at this many times the
#: resolution, then every segment of the result at the resolution (``shortcut_compiled``).
SHORTCUT_LAZY = 4
#: A shortcut gaining less than this share of the path's length is not tried: most
#: successes of a run are such slivers, each checked over its whole (long) segment; without
#: them a run costs about half the states, for paths 0.5 % longer.
SHORTCUT_LEAST_GAIN = 1e-3
#: A lazily checked segment that fails at the resolution is bent around the state at fault
#: (``planning.motion._rrt.refine_path``): draws of the bend, and bends per path at most,
#: before the shortcuts start again at the resolution.
REPAIR_TRIES = 20
REPAIR_MOST = 8


def shortcut_compiled(checker: MotionChecker, path: np.ndarray, rng: np.random.Generator,
                      resolution: float, attempts: int = 100, patience: int = 30,
                      exact: bool = False, checked: np.ndarray | None = None
                      ) -> np.ndarray | None:
    """``shortcut`` compiled: on the sphere model alone, or with ``exact`` confirming
    flagged states on the exact shapes; the path as it is without compiled kernels. Every
    segment of ``path`` must have been checked free at ``resolution`` (at its
    ``MotionChecker.steps``), or at the coarser step ``checked[i]`` (weighted rad) for
    segment ``i`` when ``checked`` is given: a shortcut keeps pieces of them without
    checking them again (``planning.motion._rrt.shortcut_run``), and every segment of the
    answer is checked at ``resolution`` here (by the shortcuts at it, or by ``refine_path``
    after the lazy pass), so the answer needs no check after it. With ``checked``, a path
    whose coarsely checked segments cannot be made free at ``resolution`` (bent about the
    states at fault) answers None: the caller searches again, checking at ``resolution``."""
    got = _compiled(checker)
    if got is None:
        return path if checked is None else None
    if len(path) <= 2 and checked is None:
        return path
    rr, work = got
    n = len(path)
    buf = np.empty((n + 2 * attempts + 3 * REPAIR_MOST + 4, checker.dof))
    buf[:n] = path
    w = np.ascontiguousarray(checker.weights)
    lo = np.ascontiguousarray(checker.lower, dtype=float)
    hi = np.ascontiguousarray(checker.upper, dtype=float)
    state = np.array([int(rng.integers(1, 2**63 - 1))], dtype=np.uint64)
    count, mode = work[-2], work[-1]
    mode[0] = 1 if exact else 0
    rr._local.checker = checker
    c0 = int(count[0])
    R, S, margin = checker._robot, checker._scene, checker.margin
    seed = state.copy()
    fine = float(resolution)
    # The steps at which the segments of ``path`` were checked.
    ns0 = np.zeros(len(buf), dtype=np.int64)
    rr.fill_steps(buf, n, fine, work, ns0)
    if checked is not None:
        for i in np.flatnonzero(np.asarray(checked, dtype=float) > fine):
            ns0[i] = checker.steps(path[i], path[i + 1], float(checked[i]))
    certified = checked is None       # every segment of ``path`` checked at ``resolution``
    passes = (SHORTCUT_LAZY * fine, fine) if SHORTCUT_LAZY > 1 else (fine,)
    for step in passes:
        # First with new segments checked at a coarser step, then each segment not yet
        # checked at ``resolution`` checked at it (bent where it fails); if that fails,
        # again at ``resolution`` (a coarsely checked path made free at it first).
        buf[:len(path)] = path
        n = len(path)
        state[:] = seed
        ns = ns0.copy()
        if n > 2:
            n = rr.reduce_path(R, S, buf, n, w, step, margin, work, ns)
            n = rr.shortcut_run(R, S, buf, n, w, step, margin, int(attempts), int(patience),
                                state, work, ns, SHORTCUT_LEAST_GAIN)
            n = rr.reduce_path(R, S, buf, n, w, step, margin, work, ns)
        if step == fine and certified:
            break
        m = rr.refine_path(R, S, buf, n, w, fine, margin, work, ns, lo, hi, state,
                           REPAIR_TRIES, REPAIR_MOST)
        if m > 0:
            n = m
            break
        if not certified:
            buf[:len(path)] = path
            ns = ns0.copy()
            m = rr.refine_path(R, S, buf, len(path), w, fine, margin, work, ns, lo, hi,
                               state, REPAIR_TRIES, REPAIR_MOST)
            if m <= 0:
                checker.checks += int(count[0]) - c0
                return None
            path = buf[:m].copy()
            rr.fill_steps(path, m, fine, work, ns0)
            certified = True
            n = m             # the answer if no pass is left: the path as found, certified
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
