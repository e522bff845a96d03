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
    ``MotionChecker`` of this thread's search (``_local.checker``); with one value more
    than the joints, at that many mm more margin (``_exact_margin``)."""
    checker = _local.checker
    q = np.array(q)
    if len(q) > checker.dof:     # a sweep's proof: the last value is the extra margin (mm)
        return bool(checker._exact_free(q[:-1], float(q[-1])))
    return bool(checker._exact_free(q))


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


# ---- swept distance -----------------------------------------------------------------------------
#: Largest clearance margin (mm) a segment's state is checked with to prove the stretch of
#: the segment about it free (``_segment_free``): a larger one flags almost every state of a
#: machine working close to a rock face or to itself, and costs more to check.
SWEEP_MARGIN_MAX = 100.0
#: Proofs are tried while they pay: the first ``PROOF_TRIALS`` of a checker, then while a
#: quarter of them succeed (the counts halved every ``PROOF_WINDOW`` tries), else on every
#: 64th checked state only. A tunnel arm's succeed 9 times in 10; a Panda's among shelves
#: seldom (a 0.01 rad step sweeps 5-10 mm there), and each failure costs a check more.
PROOF_TRIALS = 16
PROOF_WINDOW = 256
#: Least number of grid steps a stretch must span for a state to be checked with a margin
#: for it (a shorter stretch is cheaper to check state by state).
SWEEP_MIN_SPAN = 4
#: Grid steps from which a segment check looks at the clock before it starts (when a
#: deadline is armed): its stretches may be proved in far fewer states than ``_late`` counts.
SWEEP_CLOCK_STEPS = 64
#: Largest margin (mm) the exact stage proves a stretch with (past the spheres' slack): in
#: the tunnel 200 mm cut the states checked by a quarter but added as much in FCL calls.
SWEEP_EXACT_MAX = 100.0
#: Least number of grid steps a stretch must span for a state the spheres flag at its margin
#: to go to the exact stage at that margin (one FCL call against the checks it may save).
SWEEP_EXACT_SPAN = 8


@njit(**_JIT)
def _item_reach(R, e, l):
    """How far (mm) the geometry of link ``l`` carried by frame ``e`` reaches from the origin
    of the frame's body: the frame's origin for a capsule (``w == 2``: its end points are
    frames), the root sphere's far side for a rigid body (``w == 4``)."""
    X, w, root, root_r = R[4], R[6], R[7], R[8]
    if w == 2:
        return math.sqrt(X[e, 0, 3] ** 2 + X[e, 1, 3] ** 2 + X[e, 2, 3] ** 2)
    c = 0.0
    f = 0.0
    for r in range(3):
        v = 0.0
        for k in range(4):
            v += X[e, r, k] * root[l, k]
        c += v * v
        for k in range(3):
            f += X[e, r, k] * X[e, r, k]
    return math.sqrt(c) + math.sqrt(f) * root_r[l]


@njit(**_JIT)
def _link_sweep(R, a, b, cum, l, jmin):
    """An upper bound (mm) on how far any point of link ``l`` moves, in the frame of body
    ``jmin``, along the straight segment ``a``-``b``: sum over joints ``j >= jmin`` that
    move it of ``|b_j - a_j|`` times 1 (prismatic) or the largest distance from joint
    ``j``'s axis of the link's geometry (``cum``: the bounds of the chain's origins)."""
    prismatic, body, ends, w = R[1], R[3], R[5], R[6]
    n = a.shape[0]
    s = 0.0
    for j in range(jmin, n):
        d = abs(b[j] - a[j])
        if d == 0.0:
            continue
        best = -1.0
        for k in range(2 if w == 2 else 1):
            e = ends[l] + k if w == 2 else l
            bi = body[e]
            if bi < j + 1:
                continue
            r = cum[bi] - cum[j + 1] + _item_reach(R, e, l)
            if r > best:
                best = r
        if best < 0.0:
            continue
        s += d if prismatic[j] else d * best
    return s


@njit(**_JIT)
def _link_base(R, l):
    """The lowest body carrying geometry of link ``l``."""
    body, ends, w = R[3], R[5], R[6]
    if w == 2:
        return min(body[ends[l]], body[ends[l] + 1])
    return body[l]


@njit(**_JIT)
def sweeps(R, a, b, cum):
    """``(scene, self)``: upper bounds (mm) on how far any point of the robot moves along
    the segment ``a``-``b`` (the world's frame), and on how much the distance of a
    self-collision pair changes (the two links' moves in the frame of their lower body);
    ``cum (dof + 1,)`` is scratch. A joint ``j`` turning by ``dq`` moves a point at most
    ``|dq|`` times its distance from the joint's axis, which is at most the origins' chain
    from the axis to the point's body (each link's offset plus a prismatic joint's largest
    extension over the segment) plus the point's reach from that body's origin."""
    C, prismatic, offset = R[0], R[1], R[2]
    n = a.shape[0]
    cum[0] = 0.0
    for k in range(n):
        seg = math.sqrt(C[k, 0, 3] ** 2 + C[k, 1, 3] ** 2 + C[k, 2, 3] ** 2)
        if prismatic[k]:
            seg += max(abs(a[k] + offset[k]), abs(b[k] + offset[k]))
        cum[k + 1] = cum[k] + seg
    L = R[7].shape[0]
    scene = 0.0
    for l in range(L):
        s = _link_sweep(R, a, b, cum, l, 0)
        if s > scene:
            scene = s
    own = 0.0
    pairs, tab_i = R[13], R[14]
    for p in range(pairs.shape[0] + tab_i.shape[0]):
        if p < pairs.shape[0]:
            u, v = pairs[p, 0], pairs[p, 1]
        else:
            u, v = tab_i[p - pairs.shape[0], 6], tab_i[p - pairs.shape[0], 7]
        jm = min(_link_base(R, u), _link_base(R, v))
        s = _link_sweep(R, a, b, cum, u, jm) + _link_sweep(R, a, b, cum, v, jm)
        if s > own:
            own = s
    return scene, own


@njit(**_JIT)
def _exact_margin(q, extra, qx, mode):
    """Whether the exact stage finds configuration ``q`` clear by ``extra`` mm more than
    the margin: ``_exact_state`` of ``qx = [q, extra]`` (``exact_free``), asked on the
    sphere model alone too (``mode[0] == 0`` refuses what the spheres flag, never what the
    exact shapes prove free); counted in ``mode[1]``."""
    dof = q.shape[0]
    for j in range(dof):
        qx[j] = q[j]
    qx[dof] = extra
    on = np.ones(4, dtype=np.int64)
    on[1] = 0
    ok = _exact_state(qx, on)
    mode[1] += 1
    return ok


@njit(**_JIT)
def _proving(count):
    """Whether to try a sweep's proof (``PROOF_TRIALS``; ``count[1]`` tries and
    ``count[2]`` successes so far)."""
    if count[1] >= PROOF_WINDOW:
        count[1] //= 2
        count[2] //= 2
    return count[1] < PROOF_TRIALS or 4 * count[2] >= count[1] or (count[0] & 63) == 0


@njit(**_JIT)
def _segment_free(R, S, a, b, wt, res, margin, q, work):
    """Whether the segment strictly between ``a`` and ``b`` is free, on the grid of
    ``_steps`` (joint steps at most ``res``, weighted by the step weights in ``work``; the
    scratch tuple; checked states in ``work[-2][0]``, proofs tried and proved in ``[1]``
    and ``[2]``). The grid's stretches are taken in bisection order (the whole segment,
    its halves, ...). A stretch whose middle state is clear by the margin its sweep asks
    (``sweeps``: the scene's bound times the farthest part of the segment from the
    middle, the self pairs' likewise), by the spheres or, for a stretch of
    ``SWEEP_EXACT_SPAN`` grid steps or more, by the exact stage, is free everywhere: every
    point of the robot in the stretch is within that distance of where it is in the middle
    state. Otherwise (a stretch shorter than ``SWEEP_MIN_SPAN``, its margin above
    ``SWEEP_MARGIN_MAX``, proofs that seldom succeed for this checker (``_proving``), or
    its middle state not clear by it) the middle state itself must be free and the two
    halves are taken in turn; a stretch of one grid step is free when its ends are (grid
    states at most ``res`` apart, as without sweeps)."""
    T, F, M, hits, Wr, Wg, Wl, done, gaps, near_r, near_g, sw, count, mode = work
    if mode[3] != 0:
        return False
    n = _steps(a, b, sw, res)
    if n < 2:
        return True
    if mode[2] != 0 and n >= SWEEP_CLOCK_STEPS and _late(np.zeros(1, dtype=np.int64), mode):
        return False    # the clock looked at now (a count of 0 always looks)
    scr = (Wr, Wg, Wl, done, gaps, near_r, near_g)
    cum = np.empty(a.shape[0] + 1)
    qx = np.empty(a.shape[0] + 1)
    s_scene, s_self = sweeps(R, a, b, cum)
    own = R[13].shape[0] + R[14].shape[0] > 0
    # The robot without self pairs, and the scene left out: the two margins differ.
    R0 = (R[0], R[1], R[2], R[3], R[4], R[5], R[6], R[7], R[8], R[9], R[10], R[11], R[12],
          np.empty((0, 2), dtype=np.int64), np.empty((0, 8), dtype=np.int64),
          np.empty((0, 6)), np.empty(0))
    S0 = (False, S[1], S[2], S[3], S[4], S[5], S[6], S[7], S[8], S[9], S[10])
    # Breadth first (the coarse stretches before the fine: a collision is met early):
    # stretches [lo, hi] of the grid whose ends are free.
    lo = np.empty(n + 1, dtype=np.int64)
    hi = np.empty(n + 1, dtype=np.int64)
    lo2 = np.empty(n + 1, dtype=np.int64)
    hi2 = np.empty(n + 1, dtype=np.int64)
    lo[0], hi[0] = 0, n
    size = 1
    while size > 0:
        nxt = 0
        for s in range(size):
            i0, i1 = lo[s], hi[s]
            if i1 - i0 < 2:
                continue
            im = (i0 + i1) // 2
            t = im / n
            for j in range(a.shape[0]):
                q[j] = a[j] + (b[j] - a[j]) * t
            h = max(im - i0, i1 - im) / n
            m_scene = s_scene * h
            m_self = s_self * h
            m_both = max(m_scene, m_self)
            if i1 - i0 >= SWEEP_MIN_SPAN and m_both <= SWEEP_MARGIN_MAX and _proving(count):
                count[0] += 1
                count[1] += 1
                if _late(count, mode):
                    return False
                if _spheres_clear(R0, S, q, margin + m_scene, T, F, M, hits, scr) and (
                        not own or _spheres_clear(R, S0, q, margin + m_self, T, F, M,
                                                  hits, scr)):
                    count[2] += 1
                    continue
            # The spheres' slack (a tunnel's mesh balls) may be all that flags it.
            if i1 - i0 >= SWEEP_EXACT_SPAN and m_both <= SWEEP_EXACT_MAX and _proving(count):
                count[1] += 1
                if _exact_margin(q, m_both, qx, mode):
                    count[2] += 1
                    continue
            count[0] += 1
            if _late(count, mode):
                return False
            if not _spheres_clear(R, S, q, margin, T, F, M, hits, scr) \
                    and not _exact_state(q, mode):
                return False
            lo2[nxt], hi2[nxt] = i0, im
            nxt += 1
            lo2[nxt], hi2[nxt] = im, i1
            nxt += 1
        lo, lo2 = lo2, lo
        hi, hi2 = hi2, hi
        size = nxt
    return True


@njit(**_JIT)
def make_work(R, S, sw):
    """Scratch arrays for ``_segment_free``, with the joints' step weights ``sw``."""
    E = R[3].shape[0]
    L = R[7].shape[0]
    Wr, Wg, Wl, done, gaps, near_r, near_g = _scratch(L, R[9].shape[1], R[11].shape[2], S[4])
    return (np.empty((3, 4)), np.empty((E, 3, 4)), np.empty((L, 3, R[6])),
            np.empty((1, 3), dtype=np.int64), Wr, Wg, Wl, done, gaps, near_r, near_g,
            sw.copy(), np.zeros(3, dtype=np.int64), np.zeros(4, dtype=np.int64))


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
                    iterations, rng, work, out, validate):
    """Up to ``iterations`` of RRT-Connect on trees ``0`` (from the start) and ``1`` (from
    the goals) held in ``X (2, cap, dof)``, parents ``P``, live flags ``A``, fine-checked
    flags ``K`` and sizes ``N (2,)``; ``side[0]`` is the tree extended next. Edges enter at
    the ``coarse`` step and, with ``validate``, the path's edges are checked at ``fine``
    when the trees meet (without it the path is answered checked at ``coarse`` only, for a
    caller that certifies what it keeps of it). Answers ``(RUN_FOUND, K)`` with the path's
    ``K`` waypoints in ``out``, ``(RUN_BUDGET, 0)`` or ``(RUN_FULL, 0)`` when a tree is
    full."""
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
        if validate:
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
def shortcut_run(R, S, path, n, wt, fine, margin, attempts, patience, rng, work, ns,
                 least_gain=0.0):
    """Random shortcuts between points anywhere along ``path[:n]`` (capacity at least
    ``n + 2 * attempts``), in place; answers the new count. A shortcut's ends are taken
    among the states their segments were checked at (``ns``, kept up to date), so the
    pieces of the old segments it keeps consist of checked states and only the new segment
    is checked. A shortcut that would shorten the path by less than ``least_gain`` times its
    length is not checked (a failure): its segment costs as many states as a long gain's,
    and most of a run's successes are such slivers once the corners are cut."""
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
        if _dist(a, b, wt) >= old - 1e-9 - least_gain * total \
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
def _state_free(R, S, q, margin, work):
    """Whether configuration ``q`` is free (the spheres, then the exact stage as ``mode``
    says), counted like a segment's states."""
    T, F, M, hits, Wr, Wg, Wl, done, gaps, near_r, near_g, sw, count, mode = work
    if mode[3] != 0:
        return False
    count[0] += 1
    if _late(count, mode):
        return False
    return _spheres_clear(R, S, q, margin, T, F, M, hits,
                          (Wr, Wg, Wl, done, gaps, near_r, near_g)) or _exact_state(q, mode)


@njit(**_JIT)
def refine_path(R, S, path, n, wt, fine, margin, work, ns, lo, hi, rng, tries, most):
    """Check at ``fine`` every segment of ``path[:n]`` whose step count ``ns`` is coarser
    than ``fine`` asks (a lazily checked shortcut, or a piece of one), raising its count.
    A segment not free at ``fine`` was free at its coarse states: what blocks it lies
    between the two of them about the state at fault, ``c1`` and ``c2`` (checked again
    here); the stretch between them is replaced by a detour through a state drawn about
    their middle (``tries`` draws within ``lo``-``hi``, from half to twice their distance
    away), both of its segments checked at ``fine``, and the pieces before and after go on
    being refined. The path keeps its shortcuts but for a bump of about the coarse step,
    instead of being shortened again at ``fine`` from the start. Answers the new count, or
    -1 when no detour is found, ``most`` are made already or ``path`` (its rows are the
    capacity) is full."""
    dof = path.shape[1]
    q = np.empty(dof)
    x = np.empty(dof)
    c1 = np.empty(dof)
    c2 = np.empty(dof)
    y = np.empty(dof)
    sw = work[11]
    made = 0
    k = 0
    while k < n - 1:
        need = _steps(path[k], path[k + 1], sw, fine)
        if ns[k] >= need:
            k += 1
            continue
        if _segment_free(R, S, path[k], path[k + 1], wt, fine, margin, q, work):
            ns[k] = need
            k += 1
            continue
        if work[-1][3] != 0 or made >= most or n + 3 > path.shape[0]:
            return -1
        made += 1
        # The coarse states about ``q`` (the state at fault).
        num = 0.0
        den = 0.0
        for d in range(dof):
            num += (q[d] - path[k, d]) * (path[k + 1, d] - path[k, d])
            den += (path[k + 1, d] - path[k, d]) ** 2
        m = ns[k]
        i1 = min(max(int(math.floor(m * num / den)), 0), m - 1) if den > 0.0 else 0
        i2 = i1 + 1
        for d in range(dof):
            c1[d] = path[k, d] + (path[k + 1, d] - path[k, d]) * (i1 / m)
            c2[d] = path[k, d] + (path[k + 1, d] - path[k, d]) * (i2 / m)
        if i1 == 0:
            c1[:] = path[k]
        if i2 == m:
            c2[:] = path[k + 1]
        if (i1 > 0 and not _state_free(R, S, c1, margin, work)) \
                or (i2 < m and not _state_free(R, S, c2, margin, work)):
            return -1
        span = _dist(c1, c2, wt)
        found = False
        for t in range(tries):
            r = span * (0.5 + 1.5 * t / tries)
            for d in range(dof):
                v = 0.5 * (c1[d] + c2[d]) + r * (2.0 * uniform(rng) - 1.0) / wt[d]
                y[d] = min(max(v, lo[d]), hi[d])
            if _state_free(R, S, y, margin, work) \
                    and _segment_free(R, S, c1, y, wt, fine, margin, x, work) \
                    and _segment_free(R, S, y, c2, wt, fine, margin, x, work):
                found = True
                break
        if not found:
            return -1
        # path[:k+1], c1 (unless it is path[k]), y, c2 (unless it is path[k+1]), the rest.
        add = 1 + (i1 > 0) + (i2 < m)
        for j in range(n - 1, k, -1):
            path[j + add] = path[j]
            ns[j + add] = ns[j]
        w = k + 1
        if i1 > 0:
            ns[k] = i1                       # still coarse: refined next
            path[w] = c1
            w += 1
        ns[w - 1] = _steps(path[w - 1], y, sw, fine)
        path[w] = y
        ns[w] = _steps(y, c2, sw, fine)
        if i2 < m:
            path[w + 1] = c2
            ns[w + 1] = m - i2
        n += add
    return n
