"""Compiled RRT-Connect and shortcutting (numba).

The searches of ``planning.motion.search`` with every step compiled: sampling (a seeded
xorshift generator of its own, so a run depends on its seed alone, whatever else runs in the
process), nearest neighbours, edge checks (``planning.motion._kernels.check_state`` at each
state, in bisection order) and path simplification. A state the sphere stage flags counts as a
collision with ``mode[0] == 0`` (the spheres contain the robot, so every edge kept is free);
with ``mode[0] == 1`` the exact stage (FCL, in Python through ``objmode``: the checker of
the calling thread) settles it, and ``mode[1]`` counts those calls. With ``mode[2] == 1`` a
segment check looks at the clock (``_local.deadline``, ``time.perf_counter`` s) every
``DEADLINE_EVERY`` states; once it has passed, ``mode[3]`` is set and every segment check
answers "not free" at once: a search or a shortcut then keeps only what it has already
proved, and ends with its chunk.

``R`` is the robot's argument tuple and ``S`` the scene's (``MotionChecker``'s ``_robot`` and
``_scene``), unpacked by ``_spheres_clear``.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
from numba import njit, objmode

from ._kernels import _JIT, _check, _scratch, frames, link_state, nearest

#: What ``rrt_connect_run`` answers.
RUN_FOUND = 1
RUN_BUDGET = 0
RUN_FULL = 2
#: States checked between two looks at the clock (a few milliseconds of work at most).
DEADLINE_EVERY = 1024


# ---- random numbers -----------------------------------------------------------------------------
@njit(**_JIT)
def uniform(state):
    """A uniform number in [0, 1) from the xorshift64* generator ``state (1,) uint64``."""
    x = state[0]
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    state[0] = x
    y = x * np.uint64(2685821657736338717)
    return float(y >> np.uint64(11)) * (1.0 / 9007199254740992.0)


# ---- one state, one segment -------------------------------------------------------------------
_local = threading.local()


def exact_free(q: np.ndarray) -> bool:
    """The exact stage of a flagged state, for the compiled code (``objmode``): the
    ``MotionChecker`` of this thread's search (``_local.checker``)."""
    return bool(_local.checker._exact_free(np.array(q)))


def deadline_passed() -> bool:
    """Whether this thread's search deadline (``_local.deadline``) has passed."""
    deadline = getattr(_local, "deadline", None)
    return deadline is not None and time.perf_counter() >= deadline


@njit(cache=True, error_model="numpy", boundscheck=False)   # objmode: no nogil
def _late(count, mode):
    """Whether the deadline has passed: remembered in ``mode[3]``, looked up every
    ``DEADLINE_EVERY`` states while ``mode[2]`` arms it."""
    if mode[3] != 0:
        return True
    if mode[2] == 0 or count[0] % DEADLINE_EVERY != 0:
        return False
    with objmode(late="boolean"):
        late = deadline_passed()
    if late:
        mode[3] = 1
    return late


@njit(inline="always", **_JIT)
def _spheres_clear(R, S, q, margin, T, F, M, hits, scr):
    """Whether the spheres (and pair tables) clear configuration ``q``; ``scr`` is the
    ``_scratch`` tuple. Inlined into the segment check."""
    C, prismatic, offset, body, X, ends, w = R[0], R[1], R[2], R[3], R[4], R[5], R[6]
    frames(C, prismatic, offset, body, X, q, T, F)
    link_state(F, ends, w, M)
    return _check(M, margin, (R[7], R[8], R[9], R[10], R[11], R[12]), S, R[13], q,
                  (R[14], R[15], R[16]), hits, 0, scr) == 0


@njit(cache=True, error_model="numpy", boundscheck=False)   # objmode: no nogil
def _exact_state(q, mode):
    """The exact stage of a configuration the spheres flag (``mode[0] == 1``; counted in
    ``mode[1]``): whether it is free."""
    if mode[0] == 0:
        return False
    mode[1] += 1
    with objmode(ok="boolean"):
        ok = exact_free(q)
    return ok


@njit(**_JIT)
def _steps(a, b, wt, res):
    d = 0.0
    for j in range(a.shape[0]):
        v = abs(b[j] - a[j]) * wt[j]
        if v > d:
            d = v
    return max(1, int(math.ceil(d / res - 1e-12)))


@njit(**_JIT)
def _segment_free(R, S, a, b, wt, res, margin, q, work):
    """Whether the states strictly between ``a`` and ``b`` (joint steps at most ``res``,
    weighted by the step weights in ``work``) are free, taken in bisection order; ``work``
    is the scratch tuple; counts in ``work[-2][0]``."""
    T, F, M, hits, Wr, Wg, Wl, done, all_o, near_r, near_g, sw, count, mode = work
    if mode[3] != 0:
        return False
    n = _steps(a, b, sw, res)
    s = 1
    while s * 2 < n:
        s *= 2
    while s >= 1:
        for k in range(s, n, 2 * s):
            t = k / n
            for j in range(a.shape[0]):
                q[j] = a[j] + (b[j] - a[j]) * t
            count[0] += 1
            if _late(count, mode):
                return False
            if not _spheres_clear(R, S, q, margin, T, F, M, hits,
                                  (Wr, Wg, Wl, done, all_o, near_r, near_g)) \
                    and not _exact_state(q, mode):
                return False
        s //= 2
    return True


@njit(**_JIT)
def make_work(R, S, sw):
    """Scratch arrays for ``_segment_free``, with the joints' step weights ``sw``."""
    E = R[3].shape[0]
    L = R[7].shape[0]
    Wr, Wg, Wl, done, all_o, near_r, near_g = _scratch(L, R[9].shape[1], R[11].shape[2],
                                                       S[1].shape[0])
    return (np.empty((3, 4)), np.empty((E, 3, 4)), np.empty((L, 3, R[6])),
            np.empty((1, 3), dtype=np.int64), Wr, Wg, Wl, done, all_o, near_r, near_g,
            sw.copy(), np.zeros(1, dtype=np.int64), np.zeros(4, dtype=np.int64))


# ---- trees ------------------------------------------------------------------------------------
@njit(**_JIT)
def _steer(a, b, wt, step, out):
    d = 0.0
    for j in range(a.shape[0]):
        v = (b[j] - a[j]) * wt[j]
        d += v * v
    d = math.sqrt(d)
    if d <= step:
        for j in range(a.shape[0]):
            out[j] = b[j]
        return True
    f = step / d
    for j in range(a.shape[0]):
        out[j] = a[j] + (b[j] - a[j]) * f
    return False


@njit(**_JIT)
def _add(X, P, A, K, N, t, x, parent, checked):
    n = N[t]
    X[t, n] = x
    P[t, n] = parent
    A[t, n] = True
    K[t, n] = checked
    N[t] = n + 1
    return n


@njit(**_JIT)
def _kill(P, A, N, t, i):
    A[t, i] = False
    for k in range(i + 1, N[t]):
        p = P[t, k]
        if p >= 0 and not A[t, p]:
            A[t, k] = False


@njit(**_JIT)
def _validate(R, S, X, P, A, K, t, leaf, wt, fine, margin, q, work):
    """Check the unchecked edges from ``leaf`` up to its root at ``fine``; False (and the
    nodes below the failing edge dropped) if one fails."""
    i = leaf
    while i >= 0:
        p = P[t, i]
        if p >= 0 and not K[t, i]:
            if not _segment_free(R, S, X[t, p], X[t, i], wt, fine, margin, q, work):
                return False, i
            K[t, i] = True
        i = p
    return True, -1


@njit(**_JIT)
def _branch_length(P, t, i):
    n = 0
    while i >= 0:
        n += 1
        i = P[t, i]
    return n


@njit(**_JIT)
def rrt_connect_run(R, S, X, P, A, K, N, side, lo, hi, wt, step, coarse, fine, margin,
                    iterations, rng, work, out):
    """Up to ``iterations`` of RRT-Connect on trees ``0`` (from the start) and ``1`` (from
    the goals) held in ``X (2, cap, dof)``, parents ``P``, live flags ``A``, fine-checked
    flags ``K`` and sizes ``N (2,)``; ``side[0]`` is the tree extended next. Edges enter at
    the ``coarse`` step and the path's edges are checked at ``fine`` when the trees meet.
    Answers ``(RUN_FOUND, K)`` with the path's ``K`` waypoints in ``out``, ``(RUN_BUDGET,
    0)`` or ``(RUN_FULL, 0)`` when a tree is full."""
    dof = lo.shape[0]
    cap = X.shape[1]
    x = np.empty(dof)
    new = np.empty(dof)
    nxt = np.empty(dof)
    q = np.empty(dof)
    for _ in range(iterations):
        if N[0] >= cap - 64 or N[1] >= cap - 64:
            return RUN_FULL, 0
        a = side[0]
        b = 1 - a
        side[0] = b
        for j in range(dof):
            x[j] = lo[j] + (hi[j] - lo[j]) * uniform(rng)
        i = nearest(X[a], N[a], A[a], x, wt)
        _steer(X[a, i], x, wt, step, new)
        if not _segment_free(R, S, X[a, i], new, wt, coarse, margin, q, work):
            continue
        k = _add(X, P, A, K, N, a, new, i, coarse <= fine)
        j = nearest(X[b], N[b], A[b], new, wt)
        met = False
        while N[b] < cap - 1:
            reached = _steer(X[b, j], new, wt, step, nxt)
            if not _segment_free(R, S, X[b, j], nxt, wt, coarse, margin, q, work):
                break
            j = _add(X, P, A, K, N, b, nxt, j, coarse <= fine)
            if reached:
                met = True
                break
        if not met:
            continue
        ok, bad = _validate(R, S, X, P, A, K, a, k, wt, fine, margin, q, work)
        if not ok:
            _kill(P, A, N, a, bad)
            continue
        ok, bad = _validate(R, S, X, P, A, K, b, j, wt, fine, margin, q, work)
        if not ok:
            _kill(P, A, N, b, bad)
            continue
        # Start tree's branch reversed, then the goal tree's from after the meeting node.
        s_leaf = k if a == 0 else j
        g_leaf = j if a == 0 else k
        ns = _branch_length(P, 0, s_leaf)
        i = s_leaf
        for m in range(ns - 1, -1, -1):
            out[m] = X[0, i]
            i = P[0, i]
        i = P[1, g_leaf]
        m = ns
        while i >= 0:
            out[m] = X[1, i]
            m += 1
            i = P[1, i]
        return RUN_FOUND, m
    return RUN_BUDGET, 0


# ---- simplification ---------------------------------------------------------------------------
@njit(**_JIT)
def _dist(a, b, wt):
    d = 0.0
    for j in range(a.shape[0]):
        v = (b[j] - a[j]) * wt[j]
        d += v * v
    return math.sqrt(d)


@njit(**_JIT)
def fill_steps(path, n, fine, work, ns):
    """``ns[i]``: the steps at which segment ``i`` of ``path[:n]`` is checked at ``fine``
    (``_segment_free``'s)."""
    sw = work[11]
    for i in range(n - 1):
        ns[i] = _steps(path[i], path[i + 1], sw, fine)


@njit(**_JIT)
def reduce_path(R, S, path, n, wt, fine, margin, work, ns):
    """Drop waypoints of ``path[:n]`` in place: from each kept one, jump to the farthest
    later one in sight. ``ns[:n-1]``: the step counts at which the segments were checked
    (kept segments keep theirs; a jump gets the one it was checked at). Answers the new
    count."""
    q = np.empty(path.shape[1])
    keep = np.empty(n, dtype=np.int64)
    steps = np.empty(n, dtype=np.int64)
    sw = work[11]
    keep[0] = 0
    m = 1
    i = 0
    while i < n - 1:
        j = n - 1
        while j > i + 1 and not _segment_free(R, S, path[i], path[j], wt, fine, margin, q,
                                              work):
            j -= 1
        steps[m - 1] = ns[i] if j == i + 1 else _steps(path[i], path[j], sw, fine)
        keep[m] = j
        m += 1
        i = j
    for k in range(m):
        path[k] = path[keep[k]]
    for k in range(m - 1):
        ns[k] = steps[k]
    return m


@njit(**_JIT)
def _on_grid(path, i, ns, pos, cum, out):
    """The state of segment ``i`` of ``path`` nearest to arc length ``pos`` among those
    the segment was checked at (``k / ns[i]`` of the way, computed as ``_segment_free``
    computes them), into ``out``; answers ``k``."""
    seg = cum[i + 1] - cum[i]
    t = 0.0 if seg <= 0 else (pos - cum[i]) / seg
    k = min(max(int(round(t * ns[i])), 0), ns[i])
    f = k / ns[i]
    for d in range(path.shape[1]):
        out[d] = path[i, d] + (path[i + 1, d] - path[i, d]) * f
    return k


@njit(**_JIT)
def shortcut_run(R, S, path, n, wt, fine, margin, attempts, patience, rng, work, ns):
    """Random shortcuts between points anywhere along ``path[:n]`` (capacity at least
    ``n + 2 * attempts``), in place; answers the new count. A shortcut's ends are taken
    among the states their segments were checked at (``ns``, kept up to date), so the
    pieces of the old segments it keeps consist of checked states and only the new segment
    is checked."""
    dof = path.shape[1]
    q = np.empty(dof)
    a = np.empty(dof)
    b = np.empty(dof)
    cum = np.empty(path.shape[0])
    pts = np.empty((path.shape[0], dof))
    stp = np.empty(path.shape[0], dtype=np.int64)
    sw = work[11]
    fails = 0
    for _ in range(attempts):
        if n <= 2 or fails >= patience:
            break
        cum[0] = 0.0
        for i in range(n - 1):
            cum[i + 1] = cum[i] + _dist(path[i], path[i + 1], wt)
        total = cum[n - 1]
        s0 = uniform(rng) * total
        s1 = uniform(rng) * total
        if s1 < s0:
            s0, s1 = s1, s0
        i = 0
        while i < n - 2 and cum[i + 1] <= s0:
            i += 1
        j = i
        while j < n - 2 and cum[j + 1] <= s1:
            j += 1
        if j <= i:
            fails += 1
            continue
        k0 = _on_grid(path, i, ns, s0, cum, a)
        k1 = _on_grid(path, j, ns, s1, cum, b)
        old = _dist(a, path[i + 1], wt) + (cum[j] - cum[i + 1]) + _dist(path[j], b, wt)
        if _dist(a, b, wt) >= old - 1e-9 \
                or not _segment_free(R, S, a, b, wt, fine, margin, q, work):
            fails += 1
            continue
        # path[:i+1], a (unless it is path[i]), b (unless it is path[j+1]), path[j+1:n],
        # with the step counts of their segments.
        m = 0
        for k in range(i + 1):
            pts[m] = path[k]
            stp[m] = ns[k]
            m += 1
        if k0 > 0:
            stp[m - 1] = k0
            pts[m] = a
            m += 1
        head = m - 1                      # where the new segment starts
        if k1 < ns[j]:
            pts[m] = b
            stp[m] = ns[j] - k1
            m += 1
            stp[head] = _steps(pts[head], b, sw, fine)
        else:
            stp[head] = _steps(pts[head], path[j + 1], sw, fine)
        for k in range(j + 1, n):
            pts[m] = path[k]
            stp[m] = ns[k] if k < n - 1 else 0
            m += 1
        for k in range(m):
            path[k] = pts[k]
            ns[k] = stp[k]
        n = m
        fails = 0
    return n


@njit(**_JIT)
def refine_steps(R, S, path, n, wt, fine, margin, work, ns):
    """Check at ``fine`` every segment of ``path[:n]`` whose step count ``ns`` is coarser
    than ``fine`` asks (a lazily checked shortcut, or a piece of one), raising its count;
    False at the first that is not free."""
    q = np.empty(path.shape[1])
    sw = work[11]
    for k in range(n - 1):
        need = _steps(path[k], path[k + 1], sw, fine)
        if ns[k] >= need:
            continue
        if not _segment_free(R, S, path[k], path[k + 1], wt, fine, margin, q, work):
            return False
        ns[k] = need
    return True
