"""Sequencing when each node can be visited in one of several ways: a generalised TSP.

A drilling arm reaches a hole in more than one configuration (IK branches: e.g. the feed
rolled to either side of the boom), and what a move costs depends on the configurations at
both ends. Each node ``i`` has up to ``B`` alternatives, feature rows ``F[i, b] (K,)`` (NaN
rows: no such alternative); ``cost(Fa (P, K), Fb (Q, K)) -> (P, Q)`` gives the cost of
every move between two sets of alternatives (non-negative; it may depend on the direction:
the order search then works on symmetric tables, and every cost reported is directed). The
start is one alternative ``f0 (K,)`` or, without it, node 0 is visited first in whichever
alternative is best.

Method (coordinate descent between the order and the alternatives, each step exact or
improving, so the cost never rises):

1. **Order on optimistic costs.** ``W[i, j] = min over alternatives of both ends`` (a lower
   bound of any move between them) is a symmetric cost table; ``auto``'s iterated 2-opt /
   Or-opt search finds a short open path on it. The optimistic table can favour moves
   whose cheap alternatives do not chain, so the order on the table of every node in its
   first alternative (for a drilling arm: its default posture) and any orders the caller
   gives are tried as well, each scored with its best alternatives (step 2).
2. **Alternatives for the order.** For a fixed order the best alternative of every node is a
   shortest path through a layered graph (one layer per node, ``B`` states per layer):
   dynamic programming, ``O(n B^2)``, exact (``best_alternatives``).
3. **Order for the alternatives.** With every node's alternative fixed the costs form an
   ordinary table; the local search improves the order from the current one.
4. Repeat 2-3 until a round gains less than ``tol`` (relative) or ``rounds`` rounds.

Each answer is a local optimum of the order for its alternatives and the exact best
alternatives for its order; it can still miss the optimum (a pair of order and
alternatives each best for the other), so up to ``EXACT_MAX`` nodes the optimum is found
instead by dynamic programming over (visited set, last node, its alternative)
(``exact_alternatives``, Held-Karp generalised; ``O(2^n n^2 B^2)``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from kinematics.errors import FieldError

from .auto import Auto, improve_order
from .base import SequencingProblem

__all__ = [
    "EXACT_MAX",
    "CostFn",
    "BranchSequence",
    "alternative_tables",
    "best_alternatives",
    "exact_alternatives",
    "path_cost",
    "sequence_with_alternatives",
]

#: ``cost(Fa (P, K), Fb (Q, K)) -> (P, Q)``: the cost of each move between two sets of
#: alternatives.
CostFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
#: Rows of the (n, n) tables computed at once (bounds memory: rows x n x K).
ROW_BLOCK = 256
#: Most nodes ``sequence_with_alternatives`` solves exactly.
EXACT_MAX = 10


@dataclass(frozen=True)
class BranchSequence:
    """An order with an alternative per node: ``order (N,)`` node indices in visiting order,
    ``branch (N,)`` the alternative of each visited node (``branch[k]`` for node
    ``order[k]``), ``cost`` of the path from the start, ``lower_bound_cost`` of the same order
    on the optimistic table, ``history`` the cost after each round, ``runtime_s``."""

    order: np.ndarray
    branch: np.ndarray
    cost: float
    lower_bound_cost: float
    history: np.ndarray
    rounds: int
    runtime_s: float


def _check(F, f0) -> tuple[np.ndarray, np.ndarray | None]:
    F = np.asarray(F, dtype=float)
    if F.ndim != 3 or F.shape[0] < 1 or F.shape[1] < 1:
        raise FieldError("alternatives", "alternatives: must have shape (N, B, K)")
    valid = np.all(np.isfinite(F), axis=2)
    if not valid.any(axis=1).all():
        k = int(np.argmin(valid.any(axis=1)))
        raise FieldError(("alternatives", k), f"alternatives[{k}]: no alternative")
    if f0 is not None:
        f0 = np.asarray(f0, dtype=float).reshape(-1)
        if f0.shape != (F.shape[2],) or not np.all(np.isfinite(f0)):
            raise FieldError("start", f"start: must be {F.shape[2]} finite numbers")
    return F, f0


def _pair_costs(cost: CostFn, Fa: np.ndarray, Fb: np.ndarray) -> np.ndarray:
    """``cost`` with NaN rows (missing alternatives) at infinity: ``(P, K), (Q, K) -> (P, Q)``."""
    va = np.all(np.isfinite(Fa), axis=1)
    vb = np.all(np.isfinite(Fb), axis=1)
    out = np.full((len(Fa), len(Fb)), np.inf)
    if va.any() and vb.any():
        out[np.ix_(va, vb)] = cost(Fa[va], Fb[vb])
    return out


def alternative_tables(F, f0, cost: CostFn, branch=None) -> tuple[np.ndarray, np.ndarray]:
    """Symmetric move costs between nodes ``W (N, N)`` and from the start ``W0 (N,)``: the
    least over the alternatives of both ends and both directions, or, given ``branch (N,)``
    (an alternative per node), those of the given alternatives (the mean of both
    directions). Without a start ``W0`` is zero. Row blocks bound memory."""
    F, f0 = _check(F, f0)
    N, B, K = F.shape
    if branch is not None:
        G = F[np.arange(N), np.asarray(branch, dtype=int)][:, None, :]  # (N, 1, K)
    else:
        G = F
    Bg = G.shape[1]
    flat = G.reshape(N * Bg, K)
    W = np.empty((N, N))
    for r0 in range(0, N, ROW_BLOCK):
        r1 = min(N, r0 + ROW_BLOCK)
        T = _pair_costs(cost, flat[r0 * Bg : r1 * Bg], flat)  # (rows*Bg, N*Bg)
        W[r0:r1] = T.reshape(r1 - r0, Bg, N, Bg).min(axis=(1, 3))
    # A symmetric table for the order search: with given alternatives the mean of a move
    # and its reverse (equal unless the cost depends on the direction), else the least.
    W = 0.5 * (W + W.T) if branch is not None else np.minimum(W, W.T)
    np.fill_diagonal(W, 0.0)
    if f0 is None:
        W0 = np.zeros(N)
    else:
        W0 = _pair_costs(cost, f0[None], flat).reshape(N, Bg).min(axis=1)
    return W, W0


def best_alternatives(order, F, f0, cost: CostFn) -> tuple[np.ndarray, float]:
    """The best alternative of each node for the visiting ``order (N,)``: a shortest path
    through the layers (dynamic programming). Returns ``(branch (N,) per visited node, cost
    from the start)``; without a start the first node's alternative is free."""
    F, f0 = _check(F, f0)
    order = np.asarray(order, dtype=int)
    B = F.shape[1]
    if f0 is None:
        acc = np.where(np.all(np.isfinite(F[order[0]]), axis=1), 0.0, np.inf)
    else:
        acc = _pair_costs(cost, f0[None], F[order[0]])[0]
    back = np.zeros((len(order), B), dtype=int)
    for k in range(1, len(order)):
        T = _pair_costs(cost, F[order[k - 1]], F[order[k]])  # (B prev, B next)
        total = acc[:, None] + T
        back[k] = np.argmin(total, axis=0)
        acc = total[back[k], np.arange(B)]
    b = int(np.argmin(acc))
    best = float(acc[b])
    branch = np.empty(len(order), dtype=int)
    for k in range(len(order) - 1, -1, -1):
        branch[k] = b
        b = back[k, b]
    return branch, best


def exact_alternatives(F, f0, cost: CostFn) -> tuple[np.ndarray, np.ndarray, float]:
    """The cheapest order and alternatives by dynamic programming: ``cost[S, j, b]`` = least
    cost from the start through the set ``S`` ending at node ``j`` in alternative ``b``,
    one vectorised layer per set size. Returns ``(order (N,), branch (N,) per visited node,
    cost)``; without a start node 0 is first. ``ValueError`` above ``EXACT_MAX`` nodes."""
    F, f0 = _check(F, f0)
    N, B, K = F.shape
    if N > EXACT_MAX:
        raise ValueError(f"exact_alternatives takes at most {EXACT_MAX} nodes, got {N}")
    flat = F.reshape(N * B, K)
    T = _pair_costs(cost, flat, flat).reshape(N, B, N, B)
    full = (1 << N) - 1
    acc = np.full((1 << N, N, B), np.inf)
    parent = np.full((1 << N, N, B, 2), -1, dtype=np.int64)
    first = [0] if f0 is None else range(N)
    for j in first:
        if f0 is None:
            acc[1 << j, j] = np.where(np.all(np.isfinite(F[j]), axis=1), 0.0, np.inf)
        else:
            acc[1 << j, j] = _pair_costs(cost, f0[None], F[j])[0]
    masks = np.arange(1 << N)
    popcount = np.array([bin(x).count("1") for x in range(1 << N)])
    for size in range(2, N + 1):
        layer = masks[popcount == size]
        for j in range(N):
            S = layer[(layer >> j) & 1 == 1]
            if not len(S):
                continue
            prev = acc[S ^ (1 << j)].reshape(len(S), N * B)  # (M, N*B)
            cand = prev[:, :, None] + T[:, :, j, :].reshape(N * B, B)[None]  # (M, N*B, B)
            k = np.argmin(cand, axis=1)  # (M, B)
            acc[S, j] = np.take_along_axis(cand, k[:, None, :], axis=1)[:, 0]
            parent[S, j, :, 0] = k // B
            parent[S, j, :, 1] = k % B
    j, b = np.unravel_index(int(np.argmin(acc[full])), (N, B))
    total = float(acc[full, j, b])
    order, branch = [], []
    S = full
    while j >= 0:
        order.append(int(j))
        branch.append(int(b))
        pj, pb = parent[S, j, b]
        S ^= 1 << int(j)
        j, b = int(pj), int(pb)
    return np.array(order[::-1]), np.array(branch[::-1]), total


def path_cost(order, branch, F, f0, cost: CostFn) -> float:
    """Cost of visiting ``order (N,)`` in alternatives ``branch (N,)`` from the start."""
    F, f0 = _check(F, f0)
    G = F[np.asarray(order, dtype=int), np.asarray(branch, dtype=int)]
    steps = [cost(G[k - 1 : k], G[k : k + 1])[0, 0] for k in range(1, len(G))]
    first = 0.0 if f0 is None else float(cost(f0[None], G[:1])[0, 0])
    return first + float(np.sum(steps))


def _problem(W: np.ndarray, W0: np.ndarray, start: bool) -> SequencingProblem:
    if start:
        return SequencingProblem.from_costs(W, W0, name="costs")
    return SequencingProblem.from_costs(W, None, name="costs")


def sequence_with_alternatives(F, f0, cost: CostFn, *, seed: int = 0,
                               params: Auto | None = None, sequencer=None, rounds: int = 6,
                               candidates=(), tol: float = 1e-9,
                               time_limit: float | None = None,
                               clock: Callable[[], float] = time.perf_counter
                               ) -> BranchSequence:
    """Visiting order and alternatives of the nodes with alternatives ``F (N, B, K)`` (NaN
    rows: none) from ``f0 (K,)`` (None: node 0 first), minimising ``cost`` (module
    docstring). ``params``: the ``auto`` search of the rounds (its kicks, stall and
    neighbours; its time limit, or ``time_limit`` s, bounds the whole run); ``sequencer``:
    what finds the first order on the optimistic table (default: ``params``), and on the
    table of every node in its first alternative (when all have one). With a single
    alternative per node the tables are the same and no round runs. Up to ``EXACT_MAX``
    nodes the answer is exact (``exact_alternatives``). ``candidates``: orders
    (node indices) also tried as the first order; the cheapest of all is kept. The time
    limit defaults to ``rounds + 2`` times ``params``'. Seeded and reproducible when not cut
    short by the time limit."""
    F, f0 = _check(F, f0)
    t0 = clock()
    N, B = F.shape[:2]
    params = params or Auto()
    sequencer = sequencer or params
    limit = time_limit if time_limit is not None else \
        (rounds + 2) * params.time_budget(max(N - 1, 1))
    deadline = t0 + limit
    rng = np.random.default_rng(seed)
    W, W0 = alternative_tables(F, f0, cost)
    if N == 1:
        branch, total = best_alternatives(np.zeros(1, dtype=int), F, f0, cost)
        return BranchSequence(np.zeros(1, dtype=int), branch, total, float(W0[0]),
                              np.array([total]), 0, clock() - t0)
    lb = _problem(W, W0, f0 is not None)
    if N <= EXACT_MAX:
        order, branch, total = exact_alternatives(F, f0, cost)
        return BranchSequence(order, branch, total, float(lb.length(lb.free_order(order))),
                              np.array([total]), 0, clock() - t0)

    def solve(problem: SequencingProblem) -> np.ndarray:
        res = sequencer.solve(problem, rng, clock=clock) if isinstance(sequencer, Auto) \
            else sequencer.solve(problem, rng)
        return np.asarray(res.order, dtype=int)

    orders = [solve(lb), *(np.asarray(c, dtype=int) for c in candidates)]
    first = np.all(np.isfinite(F[:, 0]), axis=1)
    if B > 1 and first.all():  # every node in its first alternative: an ordinary table
        orders.append(solve(_problem(*alternative_tables(F, f0, cost, np.zeros(N, int)),
                                     f0 is not None)))
    scored = [(*best_alternatives(o, F, f0, cost), k) for k, o in enumerate(orders)]
    branch, total, k = min(scored, key=lambda x: (x[1], x[2]))
    order = orders[k]
    bound = float(lb.length(lb.free_order(order)))
    history = [total]
    done = 0
    for _ in range(rounds if B > 1 else 0):
        if clock() >= deadline:
            break
        Wf, W0f = alternative_tables(F, f0, cost, branch=_per_node(order, branch, N))
        fixed = _problem(Wf, W0f, f0 is not None)
        free = fixed.free_order(order)
        better = improve_order(fixed, free, kicks=params.kick_budget(fixed.n) // 2,
                               seed=int(rng.integers(2**63)), stall=params.stall,
                               span=params.kick_span, neighbours=params.neighbours,
                               lk_depth=params.lk_depth,
                               deadline=deadline, clock=clock)
        new_order = fixed.hole_order(better)
        new_branch, new_total = best_alternatives(new_order, F, f0, cost)
        done += 1
        if new_total < total - tol * max(1.0, total):
            order, branch, total = new_order, new_branch, new_total
            history.append(total)
        else:
            break
    return BranchSequence(order, branch, total, bound, np.array(history), done, clock() - t0)


def _per_node(order: np.ndarray, branch: np.ndarray, N: int) -> np.ndarray:
    """Alternatives indexed by node from alternatives in visiting order."""
    out = np.zeros(N, dtype=int)
    out[order] = branch
    return out
