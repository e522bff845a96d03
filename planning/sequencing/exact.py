"""Exact hole sequencing for small problems: Held-Karp dynamic programming over subsets of
the free holes, and brute force for tests."""

from __future__ import annotations

import itertools

import numpy as np

from kinematics.errors import FieldError

from .base import SequencingProblem

__all__ = ["EXACT_MAX", "held_karp", "brute_force"]

#: Most free nodes the exact dynamic programme accepts (2^n n^2 work).
EXACT_MAX = 16


# ---- Held-Karp for open paths ----------------------------------------------------------
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
