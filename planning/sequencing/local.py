"""Constructive start and local search for hole sequencing: nearest neighbour, 2-opt and
Or-opt moves on the extended path (both ends fixed), their best-improvement descent with
don't-look bits, and the double-bridge kick."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .base import IMPROVE_EPS, SequencingProblem

__all__ = [
    "FULL_SCAN_MAX",
    "nearest_neighbour",
    "two_opt_move",
    "or_opt_move",
    "two_opt",
    "or_opt",
    "local_search",
    "double_bridge",
]

#: Up to this many free holes a local-search step scans every move (one vectorised pass is
#: cheaper than two partial ones); above, only moves at active holes (don't-look bits).
FULL_SCAN_MAX = 120


# ---- constructive and local search ---------------------------------------------------------
def nearest_neighbour(problem: SequencingProblem, first: int | None = None) -> np.ndarray:
    """Greedy order: from the start (or from free node ``first``) always to the nearest
    unvisited hole. ``(n,)``."""
    n = problem.n
    seen = np.zeros(n, dtype=bool)
    order = np.empty(n, dtype=int)
    row = problem.d0.copy() if first is None else None
    for k in range(n):
        if k == 0 and first is not None:
            j = first
        else:
            r = np.where(seen, np.inf, row)
            j = int(np.argmin(r))
        order[k] = j
        seen[j] = True
        row = problem.D[j]
    return order


def _ext(problem: SequencingProblem, order: np.ndarray) -> np.ndarray:
    n = problem.n
    return np.concatenate([[n], np.asarray(order, dtype=int), [n + 1]])


def _segments(n: int, max_segment: int) -> tuple[np.ndarray, np.ndarray]:
    """Every Or-opt segment of the extended path: start positions and lengths ``(S,)``."""
    starts, lens = [], []
    for L in range(1, min(max_segment, n - 1) + 1):
        i = np.arange(1, n - L + 2)
        starts.append(i)
        lens.append(np.full(len(i), L))
    if not starts:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    return np.concatenate(starts), np.concatenate(lens)


def _two_opt_block(E: np.ndarray, T: np.ndarray, I: np.ndarray, J: np.ndarray
                   ) -> tuple[float, int, int]:
    """Best 2-opt move reversing ``T[i..j]`` for ``i in I``, ``j in J``, ``i < j`` (positions
    ``1..n`` of the extended path ``T (n+2,)``, ends fixed). Returns ``(delta mm, i, j)``."""
    if len(I) == 0 or len(J) == 0:
        return 0.0, 0, 0
    ti, tp = T[I], T[I - 1]
    tj, tn = T[J], T[J + 1]
    delta = (E[tp[:, None], tj[None, :]] + E[ti[:, None], tn[None, :]]
             - E[tp, ti][:, None] - E[tj, tn][None, :])
    delta = np.where(J[None, :] > I[:, None], delta, np.inf)
    k = int(np.argmin(delta))
    a, b = divmod(k, len(J))
    return float(delta[a, b]), int(I[a]), int(J[b])


def _or_opt_block(E: np.ndarray, T: np.ndarray, starts: np.ndarray, lens: np.ndarray,
                  K: np.ndarray) -> tuple[float, int, int, int, bool]:
    """Best Or-opt move: segment ``T[i:i+L]`` (``i, L`` from ``starts, lens``) taken out and
    put, possibly reversed, between ``T[k]`` and ``T[k+1]`` for ``k in K``. Returns
    ``(delta mm, i, L, k, reversed)``."""
    if len(starts) == 0 or len(K) == 0:
        return 0.0, 0, 0, 0, False
    a, b = T[starts], T[starts + lens - 1]
    p, nx = T[starts - 1], T[starts + lens]
    gain = E[p, a] + E[b, nx] - E[p, nx]
    u, v = T[K], T[K + 1]
    edge = E[u, v]
    bad = (K[None, :] >= (starts - 1)[:, None]) & (K[None, :] <= (starts + lens - 1)[:, None])
    # both orientations at once: (2, S, K); row 0 keeps the segment's direction
    x = np.stack([a, b])[:, :, None]
    y = np.stack([b, a])[:, :, None]
    delta = E[u[None, None, :], x] + E[y, v[None, None, :]] - (edge + gain[:, None])[None]
    delta[:, bad] = np.inf
    idx = int(np.argmin(delta))
    rv, rest = divmod(idx, delta.shape[1] * delta.shape[2])
    s_, c = divmod(rest, delta.shape[2])
    d = float(delta[rv, s_, c])
    if d >= 0:
        return 0.0, 0, 0, 0, False
    return d, int(starts[s_]), int(lens[s_]), int(K[c]), bool(rv)


@lru_cache(maxsize=64)
def _scan_masks(n: int, max_segment: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """Additive masks (0 or inf) of the moves ``_full_scan`` must skip: 2-opt ``(n, n)``
    with ``j <= i``, and per Or-opt segment length ``L`` ``(n-L+1, n+1)`` with the
    insertion edge inside or next to the segment."""
    two = np.zeros((n, n))
    two[np.tril_indices(n)] = np.inf
    kk = np.arange(n + 1)[None, :]
    ors = []
    for L in range(1, min(max_segment, n - 1) + 1):
        i = np.arange(1, n - L + 2)[:, None]
        ors.append(np.where((kk >= i - 1) & (kk <= i + L - 1), np.inf, 0.0))
    for a in (two, *ors):
        a.setflags(write=False)
    return two, ors


def _full_scan(E: np.ndarray, T: np.ndarray, max_segment: int
               ) -> tuple[tuple[float, int, int], tuple[float, int, int, int, bool]]:
    """Best 2-opt and best Or-opt move over *every* candidate, from the distance matrix
    reordered along the path, ``M = E[T][:, T]``, so each family of moves is a few slices of
    ``M`` (no scattered gathers). Same results as the ``_block`` functions on all moves."""
    n = len(T) - 2
    M = E[T][:, T]
    step = np.diagonal(M, 1)  # step[k] = M[k, k+1], k = 0..n
    two_mask, or_masks = _scan_masks(n, max_segment)
    best2: tuple[float, int, int] = (0.0, 0, 0)
    if n >= 2:
        delta = M[0:n, 1 : n + 1] + M[1 : n + 1, 2 : n + 2]
        delta -= step[:n, None]
        delta -= step[None, 1:]
        delta += two_mask
        k = int(delta.argmin())
        i, j = divmod(k, n)
        if delta[i, j] < 0:
            best2 = (float(delta[i, j]), i + 1, j + 1)
    best3: tuple[float, int, int, int, bool] = (0.0, 0, 0, 0, False)
    rows = np.arange(n + 2)
    for L, mask in enumerate(or_masks, start=1):
        S = n - L + 1  # segment starts i = 1..S
        gain = step[0:S] + step[L : n + 1] - M[rows[:S], rows[L + 1 : n + 2]]
        base = step[None, :] + gain[:, None] - mask
        for rv, delta in ((False, M[0 : n + 1, 1 : S + 1].T + M[L : n + 1, 1 : n + 2]),
                          (True, M[0 : n + 1, L : n + 1].T + M[1 : S + 1, 1 : n + 2])):
            delta -= base
            idx = int(delta.argmin())
            a, c = divmod(idx, n + 1)
            if delta[a, c] < best3[0]:
                best3 = (float(delta[a, c]), a + 1, L, c, rv)
    return best2, best3


def two_opt_move(E: np.ndarray, T: np.ndarray) -> tuple[float, int, int]:
    """Best 2-opt move on the extended path ``T (n+2,)`` (ends fixed): reverse ``T[i..j]``,
    ``1 <= i < j <= n``. Returns ``(delta mm, i, j)``; delta >= 0 means none improves."""
    pos = np.arange(1, len(T) - 1)
    return _two_opt_block(E, T, pos, pos)


def or_opt_move(E: np.ndarray, T: np.ndarray, max_segment: int = 3
                ) -> tuple[float, int, int, int, bool]:
    """Best Or-opt move on ``T (n+2,)``: take the segment ``T[i:i+L]`` (L <= max_segment) out
    and put it, possibly reversed, between ``T[k]`` and ``T[k+1]``. Returns
    ``(delta, i, L, k, reversed)``; delta >= 0 means none improves."""
    n = len(T) - 2
    starts, lens = _segments(n, max_segment)
    return _or_opt_block(E, T, starts, lens, np.arange(n + 1))


def _apply_or(T: np.ndarray, i: int, L: int, k: int, rv: bool) -> np.ndarray:
    seg = T[i : i + L]
    seg = seg[::-1] if rv else seg
    rest = np.concatenate([T[:i], T[i + L :]])
    pos = k + 1 if k < i else k + 1 - L  # insert after old T[k]
    return np.concatenate([rest[:pos], seg, rest[pos:]])


def local_search(problem: SequencingProblem, order, *, active=None,
                 max_moves: int = 100_000, max_segment: int = 3) -> np.ndarray:
    """2-opt and Or-opt (segments of 1..``max_segment`` holes, either way round) to a local
    optimum of the open path; at each step the best improving move of either kind.
    ``(n,) -> (n,)``.

    ``active`` (free-node ids, default all) are don't-look bits: only moves that break an
    edge at an active hole are scanned, and the holes a move touches become active; a hole
    goes quiet when no move breaking an edge at it improves. After a local kick this scans
    ``O(active * n)`` moves per step instead of ``O(n^2)``.
    """
    E, T = problem.E, _ext(problem, order)
    n = problem.n
    on = np.ones(n + 2, dtype=bool) if active is None else np.zeros(n + 2, dtype=bool)
    if active is not None:
        on[np.asarray(active, dtype=int)] = True
    on[[n, n + 1]] = False
    all_pos = np.arange(1, n + 1)
    starts_all, lens_all = _segments(n, max_segment)
    edges_all = np.arange(n + 1)
    for _ in range(max_moves):
        pos_on = np.zeros(n + 2, dtype=bool)
        pos_on[1 : n + 1] = on[T[1 : n + 1]]
        if not pos_on.any():
            break
        if n <= FULL_SCAN_MAX:  # small: one full scan costs less than two partial ones
            best2, best3 = _full_scan(E, T, max_segment)
        else:
            # A 2-opt move (i, j) breaks edges (i-1, i) and (j, j+1).
            I = all_pos[pos_on[1 : n + 1] | pos_on[0:n]]
            J = all_pos[pos_on[1 : n + 1] | pos_on[2 : n + 2]]
            best2 = min(_two_opt_block(E, T, I, all_pos), _two_opt_block(E, T, all_pos, J))
            # An Or-opt move breaks (i-1, i), (i+L-1, i+L) and the insertion edge (k, k+1).
            s_on = (pos_on[starts_all - 1] | pos_on[starts_all]
                    | pos_on[starts_all + lens_all - 1] | pos_on[starts_all + lens_all])
            K = edges_all[pos_on[edges_all] | pos_on[edges_all + 1]]
            best3 = min(
                _or_opt_block(E, T, starts_all[s_on], lens_all[s_on], edges_all),
                _or_opt_block(E, T, starts_all, lens_all, K),
            )
        if min(best2[0], best3[0]) >= -IMPROVE_EPS:
            break
        if best2[0] <= best3[0]:
            _, i, j = best2
            touched = T[[i - 1, i, j, j + 1]]
            T[i : j + 1] = T[i : j + 1][::-1]
        else:
            _, i, L, k, rv = best3
            touched = T[[i - 1, i, i + L - 1, i + L, k, k + 1]]
            T = _apply_or(T, i, L, k, rv)
        on[touched] = True
        on[[n, n + 1]] = False
    return T[1:-1].copy()


def two_opt(problem: SequencingProblem, order, max_moves: int = 100_000) -> np.ndarray:
    """Best-improvement 2-opt on an open path until no move shortens it. ``(n,) -> (n,)``."""
    E, T = problem.E, _ext(problem, order)
    for _ in range(max_moves):
        d, i, j = two_opt_move(E, T)
        if d >= -IMPROVE_EPS:
            break
        T[i : j + 1] = T[i : j + 1][::-1]
    return T[1:-1].copy()


def or_opt(problem: SequencingProblem, order, max_moves: int = 100_000,
           max_segment: int = 3) -> np.ndarray:
    """Best-improvement Or-opt (segments of 1..3 holes moved, either way round)."""
    E, T = problem.E, _ext(problem, order)
    for _ in range(max_moves):
        d, i, L, k, rv = or_opt_move(E, T, max_segment)
        if d >= -IMPROVE_EPS:
            break
        T = _apply_or(T, i, L, k, rv)
    return T[1:-1].copy()


def double_bridge(order: np.ndarray, rng: np.random.Generator,
                  max_segment: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Open-path double bridge: ``A B C D -> A C B D`` with random cuts (segments B and C
    at most ``max_segment`` holes), a kick 2-opt and Or-opt cannot undo in one move.
    Returns the new order ``(n,)`` and the holes whose path edges changed."""
    n = len(order)
    if n < 4:
        return rng.permutation(order), np.asarray(order)
    m = n if max_segment is None else max(2, min(n, max_segment))
    lb = int(rng.integers(1, max(2, min(m, n - 2) + 1)))
    lc = int(rng.integers(1, max(2, min(m, n - lb - 1) + 1)))
    a = int(rng.integers(0, n - lb - lc + 1))
    B = order[a : a + lb]
    C = order[a + lb : a + lb + lc]
    new = np.concatenate([order[:a], C, B, order[a + lb + lc :]])
    cut = [a - 1, a, a + lb - 1, a + lb, a + lb + lc - 1, a + lb + lc]
    touched = order[[c for c in cut if 0 <= c < n]]
    return new, touched
