"""Hole sequencing: the open path through a set of holes, and what every sequencer shares.

The problem (paper 002, section 3.2.1, eqs. 4-5): the drill visits every hole exactly once,
starting from the arm's current tool position and not returning; minimise the total travel
``D = d(start, h_1) + sum_k d(h_k, h_{k+1})`` (Euclidean, mm). Without a start position the
first hole of the list is the start (and is drilled first).

Internally a sequencer works on *free nodes*: the holes other than a start hole, numbered
``0..n-1``, with distances ``D (n, n)`` between them and ``d0 (n,)`` from the start. An
*order* is a permutation ``(n,)`` of free nodes; a batch of orders is ``(B, n)``. The local
searches use an extended matrix ``E (n+2, n+2)`` where node ``n`` is the start and node
``n+1`` a dummy end at distance 0 from everything, so the open path is the sequence
``[start, order..., end]`` with both ends fixed.

Every sequencer is a frozen dataclass of its parameters (defaults = the paper's) with
``solve(problem, rng, *, progress=None, max_evaluations=None) -> SequenceResult``; it takes a
seeded ``numpy.random.Generator``, keeps a convergence history (best length after each
iteration) and reports progress through ``Tracker``, as the continuous optimisers in
``planning.optimisers`` do.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np
from scipy.spatial import cKDTree

from kinematics.errors import FieldError, loc_from_path

from ..optimisers.base import BudgetExhausted, ProgressFn

__all__ = [
    "bad_param",
    "DUPLICATE_TOL",
    "MAX_HOLES",
    "EXACT_MAX",
    "check_holes",
    "SequencingProblem",
    "SequenceResult",
    "Tracker",
    "BudgetExhausted",
    "ProgressFn",
    "held_karp",
    "nearest_neighbour",
    "two_opt",
    "or_opt",
    "local_search",
    "double_bridge",
]

#: Two holes closer than this (mm) are the same hole.
DUPLICATE_TOL = 1.0
#: Most holes one sequencing problem takes (a face has a few hundred).
MAX_HOLES = 5000
#: Most free nodes the exact dynamic programme accepts (2^n n^2 work).
EXACT_MAX = 16
#: Improvements smaller than this (mm) do not count (round-off).
IMPROVE_EPS = 1e-9
#: Up to this many free holes a local-search step scans every move (one vectorised pass is
#: cheaper than two partial ones); above, only moves at active holes (don't-look bits).
FULL_SCAN_MAX = 120


def bad_param(name: str, message: str) -> FieldError:
    """A sequencer parameter out of range: ``FieldError`` at ``params.<name>``."""
    return FieldError(("params", name), f"params.{name}: {message}")


def check_holes(holes, name: str = "holes", *, min_count: int = 2,
                labels: list[str] | None = None) -> np.ndarray:
    """Validate a hole list: ``(N, 3)`` finite numbers (mm), at least ``min_count`` holes,
    no two within ``DUPLICATE_TOL`` of each other. Returns it as float64 ``(N, 3)``.

    Raises ``FieldError`` naming the field and the hole at fault, e.g. ``("holes", 7)``:
    ``"holes[7]: duplicate of holes[2] ..."`` (``labels[k]`` instead of ``holes[k]`` when
    given, e.g. ``"holes.left[3]"``; ``name`` and the labels are field paths).
    """
    def label(k: int) -> str:
        return labels[k] if labels is not None else f"{name}[{k}]"

    def bad(path: str, message: str) -> FieldError:
        return FieldError(loc_from_path(path), f"{path}: {message}")

    try:
        P = np.array(holes, dtype=float)
    except (TypeError, ValueError):
        raise bad(name, "must be a list of [x, y, z] in mm") from None
    if P.ndim == 1 and P.size == 0:
        P = P.reshape(0, 3)
    if P.ndim != 2 or P.shape[1] != 3:
        raise bad(name, f"must have shape (N, 3), got {list(P.shape)}")
    nonfinite = ~np.all(np.isfinite(P), axis=1)
    if nonfinite.any():
        raise bad(label(int(np.argmax(nonfinite))), "has a NaN or infinite coordinate")
    if len(P) < min_count:
        raise bad(name, f"need at least {min_count} holes, got {len(P)}")
    if len(P) > MAX_HOLES:
        raise bad(name, f"at most {MAX_HOLES} holes, got {len(P)}")
    pairs = cKDTree(P).query_pairs(DUPLICATE_TOL, output_type="ndarray") if len(P) else []
    if len(pairs):
        pairs = np.sort(pairs, axis=1)
        i, j = pairs[np.lexsort((pairs[:, 0], pairs[:, 1]))][0]
        raise bad(label(j), f"duplicate of {label(i)} (within {DUPLICATE_TOL:g} mm: "
                  f"{P[j].round(3).tolist()})")
    return P


@dataclass(frozen=True, eq=False)
class SequencingProblem:
    """An open-path sequencing problem on ``holes (N, 3)`` (mm) from ``start (3,)``.

    ``start_hole`` is True when no start was given: ``start = holes[0]`` and hole 0 is drilled
    first. ``free (n,)`` maps free node -> hole index; ``D (n, n)`` and ``d0 (n,)`` are the
    distances between free nodes and from the start, mm.
    """

    holes: np.ndarray
    start: np.ndarray
    start_hole: bool
    free: np.ndarray
    D: np.ndarray
    d0: np.ndarray

    @classmethod
    def from_holes(cls, holes, start=None) -> SequencingProblem:
        """Validate ``holes (N, 3)`` and the optional ``start (3,)`` (mm) and build the
        distance tables. ``FieldError`` naming ``holes`` or ``start``."""
        P = check_holes(holes)
        if start is None:
            s = P[0].copy()
            free = np.arange(1, len(P))
        else:
            try:
                s = np.array(start, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise FieldError("start", "start: must be [x, y, z] in mm") from None
            if s.shape != (3,) or not np.all(np.isfinite(s)):
                raise FieldError("start", "start: must be 3 finite numbers [x, y, z] in mm")
            free = np.arange(len(P))
        Q = P[free]
        D = np.linalg.norm(Q[:, None, :] - Q[None, :, :], axis=-1)
        d0 = np.linalg.norm(Q - s, axis=1)
        for a in (P, s, free, D, d0):
            a.setflags(write=False)
        return cls(P, s, start is None, free, D, d0)

    @property
    def n(self) -> int:
        """Number of free nodes (holes to order)."""
        return len(self.free)

    @cached_property
    def E(self) -> np.ndarray:
        """Extended distances ``(n+2, n+2)``: node n = start, node n+1 = dummy end (0)."""
        n = self.n
        E = np.zeros((n + 2, n + 2))
        E[:n, :n] = self.D
        E[n, :n] = E[:n, n] = self.d0
        E.setflags(write=False)
        return E

    @cached_property
    def nn_distance(self) -> float:
        """Mean distance from a free node to its nearest other node (start included), mm:
        the natural scale of one move."""
        if self.n == 0:
            return 0.0
        E = self.E[: self.n + 1, : self.n + 1] + np.diag(np.full(self.n + 1, np.inf))
        return float(E[: self.n].min(axis=1).mean())

    def lengths(self, orders) -> np.ndarray:
        """Path lengths (mm) of a batch of free-node orders: ``(B, n) -> (B,)``."""
        o = np.asarray(orders)
        if o.shape[1] == 0:
            return np.zeros(len(o))
        return self.d0[o[:, 0]] + self.D[o[:, :-1], o[:, 1:]].sum(axis=1)

    def length(self, order) -> float:
        """Path length (mm) of one free-node order ``(n,)``."""
        return float(self.lengths(np.asarray(order)[None])[0])

    def hole_order(self, order) -> np.ndarray:
        """Free-node order ``(n,)`` -> hole indices in drilling order ``(N,)``."""
        o = self.free[np.asarray(order, dtype=int)]
        return np.concatenate([[0], o]) if self.start_hole else o

    def free_order(self, hole_order) -> np.ndarray:
        """Inverse of ``hole_order``: hole indices ``(N,)`` -> free-node order ``(n,)``.
        ``FieldError`` naming ``order`` if it is not a permutation of the holes (with hole 0
        first when the start is hole 0)."""
        h = np.asarray(hole_order, dtype=int).reshape(-1)
        if sorted(h.tolist()) != list(range(len(self.holes))):
            raise FieldError("order", "order: must be a permutation of the hole indices")
        if self.start_hole:
            if h[0] != 0:
                raise FieldError("order", "order: must start with hole 0 (the start)")
            h = h[1:]
        inv = np.empty(len(self.holes), dtype=int)
        inv[self.free] = np.arange(self.n)
        return inv[h]


@dataclass(frozen=True)
class SequenceResult:
    """A drilling order: ``order (N,)`` hole indices, ``length`` of the open path from the
    start (mm), ``history`` = best length after each iteration (mm)."""

    order: np.ndarray
    length: float
    history: np.ndarray
    runtime_s: float
    evaluations: int
    iterations: int
    algorithm: str
    message: str = ""
    extra: dict = field(default_factory=dict)


class Tracker:
    """Counts path evaluations, keeps the best order and the history, reports progress.

    ``evaluate(orders)`` returns lengths and raises ``BudgetExhausted`` once
    ``max_evaluations`` is spent (after scoring what fits); ``end_iteration()`` appends the
    best-so-far to the history and calls ``progress(iteration / iterations)``, which may raise
    to stop the run (job cancellation).
    """

    def __init__(self, problem: SequencingProblem, iterations: int,
                 progress: ProgressFn | None = None, max_evaluations: int | None = None):
        self.problem = problem
        self.iterations = max(1, int(iterations))
        self.progress = progress
        self.max_evaluations = max_evaluations
        self.evaluations = 0
        self.best_order: np.ndarray | None = None
        self.best_length = math.inf
        self.history: list[float] = []
        self._t0 = time.perf_counter()

    def offer(self, order: np.ndarray, length: float) -> None:
        """Record an order whose length is already known (no evaluation counted)."""
        if length < self.best_length - IMPROVE_EPS or self.best_order is None:
            self.best_length, self.best_order = float(length), np.array(order, dtype=int)

    def evaluate(self, orders: np.ndarray) -> np.ndarray:
        """Lengths ``(B,)`` of ``orders (B, n)``, counted against the budget."""
        orders = np.atleast_2d(orders)
        room = len(orders) if self.max_evaluations is None else \
            self.max_evaluations - self.evaluations
        if room <= 0:
            raise BudgetExhausted()
        L = self.problem.lengths(orders[:room])
        self.evaluations += len(L)
        k = int(np.argmin(L))
        self.offer(orders[k], float(L[k]))
        if len(L) < len(orders):
            raise BudgetExhausted()
        return L

    def end_iteration(self) -> None:
        self.history.append(self.best_length)
        if self.progress is not None:
            self.progress(min(1.0, len(self.history) / self.iterations))

    def result(self, algorithm: str, message: str, **extra) -> SequenceResult:
        if self.best_order is None:
            raise ValueError("the sequencer evaluated nothing")
        return SequenceResult(
            order=self.problem.hole_order(self.best_order), length=self.best_length,
            history=np.array(self.history), runtime_s=time.perf_counter() - self._t0,
            evaluations=self.evaluations, iterations=len(self.history), algorithm=algorithm,
            message=message, extra=extra,
        )


def run_tracked(tracker: Tracker, body, algorithm: str) -> SequenceResult:
    """Run ``body()`` (which returns a message) until it ends or the budget is spent."""
    try:
        message = body() or "finished"
    except BudgetExhausted:
        message = "evaluation budget spent"
    return tracker.result(algorithm, message)


# ---- exact: Held-Karp for open paths -------------------------------------------------------
def held_karp(problem: SequencingProblem) -> tuple[np.ndarray, float]:
    """Exact shortest open path from the start through every free node (dynamic programming
    over subsets, O(2^n n^2)). Returns ``(order (n,), length mm)``. ValueError above
    ``EXACT_MAX`` free nodes.

    ``cost[S, j]`` = shortest path from the start through the set ``S`` ending at ``j``;
    ``cost[{j}, j] = d0[j]``, ``cost[S, j] = min_k cost[S - {j}, k] + D[k, j]``; the answer
    is ``min_j cost[all, j]``. Each subset size is one vectorised layer.
    """
    n = problem.n
    if n > EXACT_MAX:
        raise FieldError("holes", f"holes: the exact solver takes at most {EXACT_MAX + 1} holes")
    if n == 0:
        return np.zeros(0, dtype=int), 0.0
    full = (1 << n) - 1
    cost = np.full((1 << n, n), np.inf)
    parent = np.full((1 << n, n), -1, dtype=np.int64)
    bits = 1 << np.arange(n)
    cost[bits, np.arange(n)] = problem.d0
    masks = np.arange(1 << n)
    popcount = np.array([bin(m).count("1") for m in range(1 << n)])
    D = problem.D
    for size in range(2, n + 1):
        layer = masks[popcount == size]
        for j in range(n):
            S = layer[(layer >> j) & 1 == 1]
            prev = S ^ (1 << j)
            cand = cost[prev] + D[:, j][None, :]  # (M, n): through k then to j
            k = np.argmin(cand, axis=1)
            cost[S, j] = cand[np.arange(len(S)), k]
            parent[S, j] = k
    j = int(np.argmin(cost[full]))
    length = float(cost[full, j])
    order = []
    S = full
    while j >= 0:
        order.append(j)
        k = int(parent[S, j])
        S ^= 1 << j
        j = k
    return np.array(order[::-1], dtype=int), length


def brute_force(problem: SequencingProblem) -> tuple[np.ndarray, float]:
    """Every permutation (for tests on tiny problems, n <= 8)."""
    if problem.n > 8:
        raise FieldError("holes", "holes: brute force takes at most 8 free holes")
    perms = np.array(list(itertools.permutations(range(problem.n))), dtype=int).reshape(
        -1, problem.n)
    L = problem.lengths(perms)
    k = int(np.argmin(L))
    return perms[k], float(L[k])


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


class IterativeSequencer:
    """Base of the iterative sequencers: ``solve`` runs the subclass's ``_body(problem, rng,
    tracker)`` for ``self.iterations`` generations under the tracker (budget, progress,
    history); ``name`` labels the result. Problems of three holes or fewer are solved
    exactly instead (a population has nothing to search there)."""

    name = "sequencer"
    #: Problems up to this many holes are solved by ``held_karp`` instead of ``_body``.
    EXACT_UP_TO = 3

    def solve(self, problem: SequencingProblem, rng: np.random.Generator, *,
              progress: ProgressFn | None = None,
              max_evaluations: int | None = None) -> SequenceResult:
        """Run the algorithm; the result's ``history`` has one entry per generation."""
        tr = Tracker(problem, self.iterations, progress,  # type: ignore[attr-defined]
                     max_evaluations)

        def body() -> str:
            if problem.n <= self.EXACT_UP_TO:
                return self._exact(problem, tr)
            return self._body(problem, rng, tr)  # type: ignore[attr-defined]

        return run_tracked(tr, body, self.name)

    @staticmethod
    def _exact(problem: SequencingProblem, tr: Tracker) -> str:
        order, _ = held_karp(problem)
        tr.evaluate(order[None])
        tr.end_iteration()
        return "solved exactly (3 holes or fewer to order)"
