"""2-opt, Or-opt and Lin-Kernighan chains with neighbour lists and don't-look bits, and the
iterated local search built on them: the engine of ``auto`` above a dozen holes.

The open path from a fixed start is kept as a *cycle* over ``m = n + 2`` nodes (free holes
``0..n-1``, the start ``s = n``, a dummy end ``d = n + 1`` at cost 0 from every node) whose
edge ``(s, d)`` is never broken: reading the cycle from ``s`` away from ``d`` gives the
drilling order. The cycle is an array ``tour (m,)`` with a position index ``pos (m,)``; a
2-opt move is one reversal of a stretch of it, of whichever side of the cycle is shorter
(at most ``m / 2`` swaps; the cycle, read as a set of edges, is the same either way), and
every change of the tour is made of such reversals.

Moves at an active node ``t1`` (each evaluated in O(1) from the costs of the edges it
breaks and makes; ``k`` candidates per node, nearest first):

* **2-opt**: break ``(t1, t2)`` (``t2`` its successor or predecessor) and ``(t3, t4)`` for
  ``t3`` a candidate of ``t1`` (``t4`` on the same side of ``t3``), make ``(t1, t3)``,
  ``(t2, t4)``. The list is cut at the first ``t3`` no nearer than ``t2`` (the gain
  criterion: an improving 2-opt move has one of its two new edges shorter than the edge it
  replaces at that end, so with complete lists no improving move is missed).
* **Or-opt** (3-opt "segment insertion"): a segment of 1-3 holes starting at ``t1`` taken
  out (its neighbours joined) and put, either way round, between a candidate ``c`` of
  ``t1`` and a tour neighbour of ``c``; the list is cut once ``c`` is no nearer to ``t1``
  than the removal gains. Applied as two or three sequential 2-opt moves.
* The best of these is applied. If none improves, a **Lin-Kernighan chain** (``_lk``):
  sequential 2-opt steps with positive partial gain, several candidates tried at the first
  steps (``LK_BREADTH``), the best closing kept. Depth 2 is the sequential 3-opt move.

Don't-look bits: a FIFO of *active* nodes; a node with no improving move goes quiet, every
endpoint of an applied move becomes active again, so a descent from a few active nodes
costs about their number times ``k`` evaluations plus the reversals.

Iterated local search (``ils``): a segment-local double bridge (``_kick``), a descent from
its eight endpoints, and the result kept if no longer than the best (or within
``threshold`` of it, or by a Metropolis draw at ``temperature``), else undone by replaying
the journal of reversals backwards. Randomness comes from a splitmix64 generator whose
state lives in a caller's array: a run is reproducible from its seed and may be split over
several calls (chunks) without changing its course.

Costs come from points ``X (n+1, 3)`` (Euclidean, mm; the dummy at 0 from all) or from a
dense matrix ``C (m, m)`` (any symmetric cost, e.g. boom travel time), whichever is
non-empty. Compiled with numba (``cache=True``: compiled once per machine, some 15-25 s,
then loaded from ``__pycache__`` in about 0.2 s; ``warm_up`` does either ahead of a
request). Without numba the same code runs as plain Python, slowly.
"""

from __future__ import annotations

import math
import time

import numpy as np

try:  # pragma: no cover - exercised by the environment, not the tests
    from numba import njit
    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        """Stand-in for ``numba.njit``: the function itself."""
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = [
    "HAVE_NUMBA",
    "EPS",
    "MIN_NODES",
    "Engine",
    "greedy_order",
    "warm_up",
]

#: Improvements smaller than this (cost units) do not count (round-off).
EPS = 1e-9
#: Fewest cycle nodes (free holes + start + dummy) the engine takes; fewer go to the exact
#: solver.
MIN_NODES = 8
#: Candidates tried at each step of a Lin-Kernighan chain (its length is the chain's depth).
LK_BREADTH = (5, 3, 1, 1, 1, 1)
#: The double bridge's four cuts lie within this many places along the tour.
KICK_SPAN = 60
#: Most reversals one kick's descent may log for undoing; a descent that would log more
#: stops early (still a valid tour, judged as usual).
JOURNAL = 1 << 15

# Slots of the int64 state array ``st`` shared by the kernels.
_JN = 0  # journal length
_FULL = 1  # journal full: stop descending
_MOVES = 2  # moves applied (total)
_STALL = 3  # kicks since the last improvement of the best
_KICKS = 4  # kicks done (total)
_ST_SIZE = 5


# ---- costs and the tour ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def _cost(i, j, C, X, d):
    if X.shape[0] > 0:
        if i == d or j == d:
            return 0.0
        dx = X[i, 0] - X[j, 0]
        dy = X[i, 1] - X[j, 1]
        dz = X[i, 2] - X[j, 2]
        return math.sqrt(dx * dx + dy * dy + dz * dz)
    return C[i, j]


@njit(cache=True, inline="always")
def _succ(v, tour, pos):
    m = tour.shape[0]
    p = pos[v] + 1
    return tour[p - m if p >= m else p]


@njit(cache=True, inline="always")
def _pred(v, tour, pos):
    m = tour.shape[0]
    p = pos[v] - 1
    return tour[p + m if p < 0 else p]


@njit(cache=True, inline="always")
def _nxt(v, way, tour, pos):
    """The node after ``v`` along direction ``way`` (0 forward, 1 backward)."""
    return _succ(v, tour, pos) if way == 0 else _pred(v, tour, pos)


@njit(cache=True, inline="always")
def _prv(v, way, tour, pos):
    return _pred(v, tour, pos) if way == 0 else _succ(v, tour, pos)


@njit(cache=True, inline="always")
def _between(a, b, c, way, pos, m):
    """Whether ``b`` lies on the stretch from ``a`` to ``c`` (inclusive) along ``way``."""
    if way == 0:
        return (pos[b] - pos[a] + m) % m <= (pos[c] - pos[a] + m) % m
    return (pos[a] - pos[b] + m) % m <= (pos[a] - pos[c] + m) % m


@njit(cache=True, inline="always")
def _fixed(a, b, s, d):
    return (a == s and b == d) or (a == d and b == s)


@njit(cache=True)
def _reverse(tour, pos, i, j, journal, st, log):
    """Reverse the cyclic stretch of positions ``i..j`` (inclusive, forward), or its
    complement if that is shorter; log the stretch reversed when ``log``."""
    m = tour.shape[0]
    L = (j - i + m) % m + 1
    if 2 * L > m:
        i, j = (j + 1) % m, (i - 1 + m) % m
        L = m - L
    if log and journal.shape[0] > 0:
        if st[_JN] < journal.shape[0]:
            journal[st[_JN], 0] = i
            journal[st[_JN], 1] = j
            st[_JN] += 1
        if st[_JN] >= journal.shape[0]:
            st[_FULL] = 1
    a, b = i, j
    for _ in range(L // 2):
        va, vb = tour[a], tour[b]
        tour[a], tour[b] = vb, va
        pos[vb], pos[va] = a, b
        a += 1
        if a == m:
            a = 0
        b -= 1
        if b < 0:
            b = m - 1


@njit(cache=True)
def _move2(a, b, c, e, tour, pos, journal, st):
    """2-opt: the tour edges ``(a, b)`` and ``(c, e)``, with ``b`` after ``a`` and ``e``
    after ``c`` in one direction, become ``(a, c)`` and ``(b, e)``."""
    if _succ(a, tour, pos) == b:
        _reverse(tour, pos, pos[b], pos[c], journal, st, True)
    else:
        _reverse(tour, pos, pos[c], pos[b], journal, st, True)


@njit(cache=True)
def _undo(tour, pos, journal, st):
    for k in range(st[_JN] - 1, -1, -1):
        _reverse(tour, pos, journal[k, 0], journal[k, 1], journal, st, False)
    st[_JN] = 0
    st[_FULL] = 0


@njit(cache=True)
def _push(v, queue, inq, qh, d):
    """Activate ``v`` (the FIFO ``queue`` of capacity m, head/size in ``qh``)."""
    if v == d or inq[v]:
        return
    m = queue.shape[0]
    queue[(qh[0] + qh[1]) % m] = v
    qh[1] += 1
    inq[v] = True


# ---- the descent -----------------------------------------------------------------------------
@njit(cache=True)
def _undo_to(tour, pos, journal, st, mark):
    """Undo the logged reversals after journal position ``mark``."""
    for k in range(st[_JN] - 1, mark - 1, -1):
        _reverse(tour, pos, journal[k, 0], journal[k, 1], journal, st, False)
    st[_JN] = mark


@njit(cache=True)
def _lk(t1, C, X, nbr, tour, pos, s, d, eps, journal, st, queue, inq, qh, lkb, work):
    """Lin-Kernighan chain from ``t1``: break ``(t1, t2)``, then repeatedly make
    ``(t_2i, t_2i+1)`` to a candidate of the chain's free end and break ``(t_2i+1, t_2i+2)``
    so that closing ``(t_2i+2, t1)`` leaves one cycle (each step a 2-opt move, applied and
    logged), while the partial gain stays positive and no edge made is broken again; up to
    ``len(lkb)`` steps, trying the ``lkb[i]`` best candidates at step ``i`` (ranked by
    ``c(t_2i+1, t_2i+2) - c(t_2i, t_2i+1)``). The best closing along the chain is kept (the
    steps after it undone), else everything is. Returns the gain (0: none)."""
    depth = lkb.shape[0]
    K = nbr.shape[1]
    if st[_JN] + depth + 2 > journal.shape[0]:
        st[_FULL] = 1
        return 0.0
    ct3 = work[0]
    ct4 = work[1]
    cnt = work[2, :, 0]
    idx = work[2, :, 1]
    t2s = work[2, :, 2]
    marks = work[2, :, 3]
    addA = work[2, :, 4]
    addB = work[2, :, 5]
    gains = np.empty(depth + 1)
    score = np.empty(K)
    for way in range(2):
        t2 = _nxt(t1, way, tour, pos)
        if _fixed(t1, t2, s, d):
            continue
        start = st[_JN]
        best_gain = eps
        best_jn = -1
        best_level = -1
        level = 0
        t2s[0] = t2
        gains[0] = _cost(t1, t2, C, X, d)
        marks[0] = start
        cnt[0] = _lk_candidates(t1, t2, gains[0], C, X, nbr, tour, pos, s, d, eps, ct3[0],
                                ct4[0], score, lkb[0], addA, addB, 0)
        idx[0] = 0
        while level >= 0:
            if idx[level] >= cnt[level] or (idx[level] > 0 and best_jn >= 0):
                level -= 1  # exhausted, or an improvement found: no more alternatives
                if best_jn >= 0:
                    break
                continue
            if idx[level] > 0:
                _undo_to(tour, pos, journal, st, marks[level])
            j = idx[level]
            idx[level] += 1
            t2i, t3, t4 = t2s[level], ct3[level, j], ct4[level, j]
            _move2(t2i, t1, t3, t4, tour, pos, journal, st)
            g = gains[level] - _cost(t2i, t3, C, X, d) + _cost(t3, t4, C, X, d)
            addA[level] = t2i
            addB[level] = t3
            close = g - _cost(t4, t1, C, X, d)
            if close > best_gain:
                best_gain = close
                best_jn = st[_JN]
                best_level = level
            if level + 1 < depth:
                level += 1
                t2s[level] = t4
                gains[level] = g
                marks[level] = st[_JN]
                cnt[level] = _lk_candidates(t1, t4, g, C, X, nbr, tour, pos, s, d, eps,
                                            ct3[level], ct4[level], score, lkb[level], addA,
                                            addB, level)
                idx[level] = 0
        if best_jn >= 0:
            _undo_to(tour, pos, journal, st, best_jn)
            _push(t1, queue, inq, qh, d)
            _push(t2, queue, inq, qh, d)
            for lv in range(best_level + 1):
                _push(ct3[lv, idx[lv] - 1], queue, inq, qh, d)
                _push(ct4[lv, idx[lv] - 1], queue, inq, qh, d)
            return best_gain
        _undo_to(tour, pos, journal, st, start)
    return 0.0


@njit(cache=True)
def _lk_candidates(t1, t2i, g0, C, X, nbr, tour, pos, s, d, eps, out3, out4, score, b, addA,
                   addB, level):
    """The ``b`` best next steps of an LK chain whose free end is ``t2i`` (partial gain
    ``g0``): ``(t3, t4)`` into ``out3``, ``out4``, best first; returns how many."""
    K = nbr.shape[1]
    forward = _succ(t1, tour, pos) == t2i  # t4 comes before t3 along t1 -> t2i
    found = 0
    for k in range(K):
        t3 = nbr[t2i, k]
        if t3 < 0:
            break
        g1 = g0 - _cost(t2i, t3, C, X, d)
        if g1 <= eps:
            break
        if t3 == t1:
            continue
        t4 = _pred(t3, tour, pos) if forward else _succ(t3, tour, pos)
        if t4 == t2i or _fixed(t3, t4, s, d) or (t1 == s and t4 == d):
            continue
        tabu = False
        for lv in range(level):  # never break an edge the chain made
            if (addA[lv] == t3 and addB[lv] == t4) or (addA[lv] == t4 and addB[lv] == t3):
                tabu = True
        if tabu:
            continue
        sc = _cost(t3, t4, C, X, d) - _cost(t2i, t3, C, X, d)
        # insertion into the sorted top-b
        j = min(found, b - 1) if b > 0 else -1
        if j < 0:
            break
        if found >= b and sc <= score[b - 1]:
            continue
        while j > 0 and score[j - 1] < sc:
            score[j] = score[j - 1]
            out3[j] = out3[j - 1]
            out4[j] = out4[j - 1]
            j -= 1
        score[j] = sc
        out3[j] = t3
        out4[j] = t4
        if found < b:
            found += 1
    return found


@njit(cache=True)
def _best_move(t1, C, X, nbr, tour, pos, s, d, eps, mv, prune):
    """Best improving 2-opt or Or-opt move at ``t1``: its cost change, with the move in
    ``mv`` (kind 1: 2-opt ``(t1, t2, t3, t4)``; kind 2: Or-opt ``(p1, s1, s2, n1, c, e)``,
    the segment s1..s2 between p1 and n1 put between c and e with s1 next to c)."""
    best = -eps
    K = nbr.shape[1]
    m = tour.shape[0]
    for way in range(2):  # 0: successor side, 1: predecessor side
        # 2-opt
        t2 = _succ(t1, tour, pos) if way == 0 else _pred(t1, tour, pos)
        if not _fixed(t1, t2, s, d):
            c12 = _cost(t1, t2, C, X, d)
            for k in range(K):
                t3 = nbr[t1, k]
                if t3 < 0:
                    break
                c13 = _cost(t1, t3, C, X, d)
                if c13 >= c12 - eps:
                    break
                t4 = _succ(t3, tour, pos) if way == 0 else _pred(t3, tour, pos)
                if t3 == t2 or t4 == t1 or _fixed(t3, t4, s, d):
                    continue
                delta = c13 + _cost(t2, t4, C, X, d) - c12 - _cost(t3, t4, C, X, d)
                if delta < best:
                    best = delta
                    mv[0] = 1
                    mv[1] = t1
                    mv[2] = t2
                    mv[3] = t3
                    mv[4] = t4
        # Or-opt: segments t1 .. s2 running away from p1
        if t1 == s:
            continue
        p1 = _pred(t1, tour, pos) if way == 0 else _succ(t1, tour, pos)
        s2 = t1
        for L in range(1, 4):
            if L > 1:
                s2 = _succ(s2, tour, pos) if way == 0 else _pred(s2, tour, pos)
                if s2 == s or s2 == d:
                    break
            n1 = _succ(s2, tour, pos) if way == 0 else _pred(s2, tour, pos)
            if m < L + 5:
                break
            gain = (_cost(p1, t1, C, X, d) + _cost(s2, n1, C, X, d)
                    - _cost(p1, n1, C, X, d))
            if prune and gain <= eps:
                continue
            mid = _succ(t1, tour, pos) if way == 0 else _pred(t1, tour, pos)  # L = 3 middle
            for k in range(K):
                c = nbr[t1, k]
                if c < 0:
                    break
                c1 = _cost(c, t1, C, X, d)
                if prune and c1 >= gain - eps:
                    break
                if c == t1 or c == s2 or (L == 3 and c == mid):
                    continue
                for side in range(2):
                    e = _succ(c, tour, pos) if side == 0 else _pred(c, tour, pos)
                    if e == t1 or e == s2 or (L == 3 and e == mid) or _fixed(c, e, s, d):
                        continue
                    delta = c1 + _cost(s2, e, C, X, d) - _cost(c, e, C, X, d) - gain
                    if delta < best:
                        best = delta
                        mv[0] = 2
                        mv[1] = p1
                        mv[2] = t1
                        mv[3] = s2
                        mv[4] = n1
                        mv[5] = c
                        mv[6] = e
    return best


@njit(cache=True)
def _apply(mv, tour, pos, journal, st, queue, inq, qh, d):
    """Apply the move in ``mv`` (as found by ``_best_move``) and activate its endpoints."""
    if mv[0] == 1:
        t1, t2, t3, t4 = mv[1], mv[2], mv[3], mv[4]
        _move2(t1, t2, t3, t4, tour, pos, journal, st)
        for v in (t1, t2, t3, t4):
            _push(v, queue, inq, qh, d)
        return
    p1, s1, s2, n1, c, e = mv[1], mv[2], mv[3], mv[4], mv[5], mv[6]
    # Orientation O runs p1 -> s1 .. s2 -> n1; (u, w) is the insertion edge along O.
    forward = _succ(p1, tour, pos) == s1
    c_then_e = (_succ(c, tour, pos) == e) == forward
    if c_then_e:  # s1 next to c: keep the segment's direction, u s1 .. s2 w
        u, w = c, e
        _move2(p1, s1, u, w, tour, pos, journal, st)
        _move2(p1, u, n1, s2, tour, pos, journal, st)
        _move2(u, s2, s1, w, tour, pos, journal, st)
    else:  # e before c along O: reversed insertion, e s2 .. s1 c
        u, w = e, c
        _move2(p1, s1, u, w, tour, pos, journal, st)
        _move2(p1, u, n1, s2, tour, pos, journal, st)
    for v in (p1, s1, s2, n1, c, e):
        _push(v, queue, inq, qh, d)


@njit(cache=True)
def _descend(C, X, nbr, tour, pos, s, d, queue, inq, qh, journal, st, eps, max_moves, lkb,
             prune):
    """Improve until no active node has an improving move (or ``max_moves`` moves, or the
    journal is full). Returns the total cost change (<= 0)."""
    total = 0.0
    mv = np.zeros(7, dtype=np.int64)
    m = tour.shape[0]
    moves = 0
    depth = lkb.shape[0]
    work = np.zeros((3, max(depth, 1), max(nbr.shape[1], 6)), dtype=np.int64)
    while qh[1] > 0:
        t1 = queue[qh[0]]
        qh[0] = (qh[0] + 1) % m
        qh[1] -= 1
        inq[t1] = False
        if st[_JN] + 4 > journal.shape[0]:  # a move must be undoable: stop here
            st[_FULL] = 1
            break
        delta = _best_move(t1, C, X, nbr, tour, pos, s, d, eps, mv, prune)
        if delta < -eps:
            _apply(mv, tour, pos, journal, st, queue, inq, qh, d)
            _push(t1, queue, inq, qh, d)
        elif depth > 0:
            delta = -_lk(t1, C, X, nbr, tour, pos, s, d, eps, journal, st, queue, inq, qh,
                         lkb, work)
        if delta < -eps:
            total += delta
            moves += 1
            st[_MOVES] += 1
            if moves >= max_moves or st[_FULL] == 1:
                break
    # leave nothing active for the next call
    while qh[1] > 0:
        inq[queue[qh[0]]] = False
        qh[0] = (qh[0] + 1) % m
        qh[1] -= 1
    return total


@njit(cache=True)
def descend_all(C, X, nbr, tour, pos, s, d, eps, max_moves, lkb):
    """Descent from every node active, then full passes until one changes nothing, with
    Or-opt unpruned: a local optimum of 2-opt and Or-opt over the candidate lists (exact
    when the lists are complete). Returns the cost change."""
    m = tour.shape[0]
    queue = np.empty(m, dtype=np.int64)
    inq = np.zeros(m, dtype=np.bool_)
    qh = np.zeros(2, dtype=np.int64)
    journal = np.empty((JOURNAL, 2), dtype=np.int64)
    st = np.zeros(_ST_SIZE, dtype=np.int64)
    total = 0.0
    moves = 0
    while moves < max_moves:
        for k in range(m):
            _push(tour[k], queue, inq, qh, d)
        before = st[_MOVES]
        total += _descend(C, X, nbr, tour, pos, s, d, queue, inq, qh, journal, st, eps,
                          max_moves - moves, lkb, False)
        moves += st[_MOVES] - before
        # the journal only undoes trial LK steps here: empty it whenever it fills
        st[_JN] = 0
        if st[_FULL] == 1:
            st[_FULL] = 0
        elif st[_MOVES] == before:
            break
    return total


# ---- the iterated local search ---------------------------------------------------------------
@njit(cache=True, inline="always")
def _next(rs):
    """splitmix64 step on the state ``rs[0]`` (uint64): a uniform 63-bit integer."""
    z = rs[0] + np.uint64(0x9E3779B97F4A7C15)
    rs[0] = z
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return np.int64(z >> np.uint64(1))


@njit(cache=True)
def _kick(C, X, tour, pos, s, d, span, journal, st, rs, queue, inq, qh):
    """Segment-local double bridge: the cycle cut after a random hole and after three more
    within ``span`` places along the tour, its segments ``A B C D`` joined as ``A D C B``
    (a 4-change no sequential 3-opt move or LK chain undoes; B, C and D are short, so the
    descent from its eight endpoints repairs it cheaply). Never cuts ``(s, d)``. Returns
    its cost change (0: none found)."""
    m = tour.shape[0]
    n = m - 2
    span = max(3, min(span, m - 2))
    v = np.empty(4, dtype=np.int64)
    for _ in range(50):
        v[0] = _next(rs) % n
        ok = True
        p0 = pos[v[0]]
        for i in range(1, 4):  # three more cuts within ``span`` places along the tour
            v[i] = tour[(p0 + 1 + _next(rs) % span) % m]
        for i in range(4):  # distinct nodes, none cutting (s, d)
            if _fixed(v[i], _succ(v[i], tour, pos), s, d):
                ok = False
            for j in range(i):
                if v[i] == v[j]:
                    ok = False
        if not ok:
            continue
        p0 = pos[v[0]]
        for i in range(2, 4):  # insertion sort of v[1:] by position after v[0]
            j = i
            while j > 1 and (pos[v[j]] - p0 + m) % m < (pos[v[j - 1]] - p0 + m) % m:
                t = v[j]
                v[j] = v[j - 1]
                v[j - 1] = t
                j -= 1
        a1, a2, a3, a4 = v[0], v[1], v[2], v[3]
        b1 = _succ(a1, tour, pos)
        b2 = _succ(a2, tour, pos)
        b3 = _succ(a3, tour, pos)
        b4 = _succ(a4, tour, pos)
        # A = b4..a1, B = b1..a2, C = b2..a3, D = b3..a4 -> A D C B
        delta = (_cost(a1, b3, C, X, d) + _cost(a4, b2, C, X, d) + _cost(a3, b1, C, X, d)
                 + _cost(a2, b4, C, X, d) - _cost(a1, b1, C, X, d) - _cost(a2, b2, C, X, d)
                 - _cost(a3, b3, C, X, d) - _cost(a4, b4, C, X, d))
        _move2(a1, b1, a4, b4, tour, pos, journal, st)  # A D' C' B'
        _move2(a1, a4, b3, a3, tour, pos, journal, st)  # A D C' B'
        _move2(a4, a3, b2, a2, tour, pos, journal, st)  # A D C B'
        _move2(a3, a2, b1, b4, tour, pos, journal, st)  # A D C B
        for x in (a1, a2, a3, a4, b1, b2, b3, b4):
            _push(x, queue, inq, qh, d)
        return delta
    return 0.0


@njit(cache=True)
def ils(C, X, nbr, tour, pos, s, d, length, best_tour, best_len, kicks, span, threshold,
        stall, st, rs, eps, lkb, track, temperature):
    """Up to ``kicks`` kicks of the iterated local search from ``tour`` (of cost
    ``length``), stopping early after ``stall`` kicks in a row without a new best (0: never).
    With ``track``, ``best_tour`` receives each new best tour (otherwise the current tour
    is the best). Returns ``(current cost, best cost, kicks done)``; ``st`` carries the generator
    counters and ``rs`` the generator between calls."""
    m = tour.shape[0]
    queue = np.empty(m, dtype=np.int64)
    inq = np.zeros(m, dtype=np.bool_)
    qh = np.zeros(2, dtype=np.int64)
    journal = np.empty((JOURNAL, 2), dtype=np.int64)
    done = 0
    cur = length
    for _ in range(kicks):
        if stall > 0 and st[_STALL] >= stall:
            break
        st[_JN] = 0
        st[_FULL] = 0
        delta = _kick(C, X, tour, pos, s, d, span, journal, st, rs, queue, inq, qh)
        delta += _descend(C, X, nbr, tour, pos, s, d, queue, inq, qh, journal, st, eps,
                          1 << 30, lkb, True)
        done += 1
        st[_KICKS] += 1
        new = cur + delta
        if new < best_len - eps:
            best_len = new
            st[_STALL] = 0
            cur = new
            if track:
                best_tour[:] = tour
        else:
            st[_STALL] += 1
            if new <= best_len * (1.0 + threshold) + eps:  # no longer than the best (+thr)
                cur = new
            elif temperature > 0.0 and new - cur < 30.0 * temperature and \
                    (_next(rs) >> 11) * (1.0 / 4503599627370496.0) < \
                    math.exp(-(new - cur) / temperature):
                cur = new
            else:
                _undo(tour, pos, journal, st)
    return cur, best_len, done


@njit(cache=True)
def _greedy(C, X, nbr, n, first):
    """Nearest-neighbour path from the start ``n`` (or from free node ``first`` >= 0): the
    nearest unvisited candidate, else the nearest unvisited node by a full scan."""
    seen = np.zeros(n, dtype=np.bool_)
    order = np.empty(n, dtype=np.int64)
    d = n + 1
    cur = n
    K = nbr.shape[1]
    for k in range(n):
        nxt = -1
        if k == 0 and first >= 0:
            nxt = first
        else:
            best = np.inf
            for j in range(K):
                v = nbr[cur, j]
                if v < 0:
                    break
                if v < n and not seen[v]:
                    nxt = v
                    break
            if nxt < 0:
                for v in range(n):
                    if not seen[v]:
                        c = _cost(cur, v, C, X, d)
                        if c < best:
                            best = c
                            nxt = v
        order[k] = nxt
        seen[nxt] = True
        cur = nxt
    return order


# ---- Python side -----------------------------------------------------------------------------
def greedy_order(n: int, nbr: np.ndarray, *, X: np.ndarray | None = None,
                 C: np.ndarray | None = None, first: int | None = None) -> np.ndarray:
    """Nearest-neighbour order ``(n,)`` from the start (or from free node ``first``), costs
    and candidate lists as ``Engine`` takes them."""
    X = np.zeros((0, 3)) if X is None else np.array(X, dtype=np.float64, order="C")
    C = np.zeros((0, 0)) if C is None else np.array(C, dtype=np.float64, order="C")
    return _greedy(C, X, np.array(nbr, dtype=np.int64, order="C"), n,
                   -1 if first is None else int(first))
def _cycle(order: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Free-node order ``(n,)`` -> cycle ``[s, order..., d]`` and its position index."""
    tour = np.concatenate([[n], np.asarray(order, dtype=np.int64), [n + 1]]).astype(np.int64)
    pos = np.empty(n + 2, dtype=np.int64)
    pos[tour] = np.arange(n + 2)
    return tour, pos


def _order(tour: np.ndarray, pos: np.ndarray, n: int) -> np.ndarray:
    """The free-node order of a cycle: from ``s`` away from ``d``."""
    m = n + 2
    k = int(pos[n])
    step = 1 if tour[(k - 1) % m] == n + 1 else -1
    idx = (k + step * np.arange(1, n + 1)) % m
    return tour[idx].copy()


class Engine:
    """The search state of one problem: costs (``X (n+1, 3)``: the free holes, then the
    start, mm; or ``C (n+2, n+2)`` with the start at row n and a zero row and column n+1 for
    the dummy end), neighbour lists ``nbr (n+1, k)`` over nodes ``0..n`` (-1 padded), the
    tour (from the free-node ``order (n,)``) and the generator (``seed``)."""

    def __init__(self, n: int, nbr: np.ndarray, order, *, X: np.ndarray | None = None,
                 C: np.ndarray | None = None, seed: int = 0,
                 lk: tuple[int, ...] = LK_BREADTH) -> None:
        if (X is None) == (C is None):
            raise ValueError("give exactly one of X and C")
        self.n = n
        self.s, self.d = n, n + 1
        # Own writable copies: numba compiles read-only arrays as another type.
        self.X = np.array(X, dtype=np.float64, order="C") if X is not None else \
            np.zeros((0, 3))
        self.C = np.array(C, dtype=np.float64, order="C") if C is not None else \
            np.zeros((0, 0))
        nbr = np.array(nbr, dtype=np.int64)
        if len(nbr) == n + 1:  # the dummy end has no candidates
            nbr = np.vstack([nbr, np.full((1, nbr.shape[1]), -1, dtype=np.int64)])
        if nbr.shape[0] != n + 2:
            raise ValueError(f"nbr: need {n + 1} or {n + 2} rows, got {nbr.shape[0]}")
        self.nbr = np.ascontiguousarray(nbr)
        self.tour, self.pos = _cycle(order, n)
        self.best_tour = self.tour.copy()
        self.st = np.zeros(_ST_SIZE, dtype=np.int64)
        self.rs = np.array([seed % 2**64], dtype=np.uint64)
        self.lkb = np.array(lk, dtype=np.int64)
        self.length = self.cost_of(self.order())
        self.best_length = self.length

    def cost_of(self, order) -> float:
        """Cost of the open path ``order (n,)`` from the start, by the engine's costs."""
        o = np.asarray(order, dtype=np.int64)
        path = np.concatenate([[self.s], o])
        if self.X.shape[0]:
            return float(np.linalg.norm(np.diff(self.X[path], axis=0), axis=1).sum())
        return float(self.C[path[:-1], path[1:]].sum())

    def order(self) -> np.ndarray:
        """The current order ``(n,)`` (the best one when ``threshold`` was 0)."""
        return _order(self.tour, self.pos, self.n)

    def best_order(self) -> np.ndarray:
        return _order(self.best_tour, np.argsort(self.best_tour), self.n)

    @property
    def kicks_done(self) -> int:
        return int(self.st[_KICKS])

    @property
    def stalled(self) -> int:
        return int(self.st[_STALL])

    def descend(self, max_moves: int = 1 << 30) -> float:
        """Local optimum from the current tour (``descend_all``); the new cost.
        ``predicted`` keeps the change the moves claimed (the test of their bookkeeping)."""
        self.predicted = float(descend_all(self.C, self.X, self.nbr, self.tour, self.pos,
                                           self.s, self.d, EPS, max_moves, self.lkb))
        self.length = self.cost_of(self.order())  # exact, no drift
        if self.length < self.best_length:
            self.best_length = self.length
            self.best_tour[:] = self.tour
        return self.length

    def polish(self) -> float:
        """The best tour so far made current and ``descend``ed; the new best cost."""
        if self.best_length < self.length - EPS:
            self.tour[:] = self.best_tour
            self.pos[self.tour] = np.arange(len(self.tour))
            self.length = self.best_length
        return self.descend()

    def kick(self, kicks: int, *, span: int = KICK_SPAN, threshold: float = 0.0,
             stall: int = 0, temperature: float = 0.0) -> int:
        """Run up to ``kicks`` kicks (``span``, ``threshold``, ``stall`` and
        ``temperature`` as ``ils``); returns how many ran."""
        # While the current tour is the best, the best need not be copied at each record.
        track = threshold > 0.0 or temperature > 0.0 or self.length > self.best_length + EPS
        cur, best, done = ils(self.C, self.X, self.nbr, self.tour, self.pos, self.s, self.d,
                              self.length, self.best_tour, self.best_length, int(kicks),
                              int(span), float(threshold), int(stall), self.st, self.rs,
                              EPS, self.lkb, track, float(temperature))
        self.length, self.best_length = float(cur), float(best)
        if not track:
            self.best_tour[:] = self.tour
        return int(done)


def warm_up() -> float:
    """Compile (or load from numba's cache) every kernel on a tiny problem, so no request
    pays for it. Returns the seconds it took."""
    t0 = time.perf_counter()
    rng = np.random.default_rng(0)
    n = 12
    X = rng.uniform(0, 1000, (n + 1, 3))
    D = np.linalg.norm(X[:, None] - X[None], axis=-1)
    nbr = np.argsort(D + np.diag(np.full(n + 1, np.inf)), axis=1)[:, :5]
    nbr = np.vstack([nbr, np.full((1, 5), -1)])
    C = np.zeros((n + 2, n + 2))
    C[: n + 1, : n + 1] = D
    for kw in ({"X": X}, {"C": C}):
        e = Engine(n, nbr, np.arange(n), seed=1, **kw)
        e.descend()
        e.kick(5, span=6)
        e.kick(5, span=6, threshold=0.01, temperature=1.0)
        greedy_order(n, nbr, X=kw.get("X"), C=kw.get("C"))
    return time.perf_counter() - t0
