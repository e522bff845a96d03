"""Improved genetic algorithm (IGA) for hole sequencing, paper 002 section 3.2.2, Figure 4.

The paper's loop, with its printed parameters as defaults (section 4.1): population 50,
crossover probability 0.95, mutation probability 0.05, 400 iterations; swap / reverse /
insert mutation with probabilities 0.2 / 0.5 / 0.3; simulated annealing cooling 0.99.
Chromosomes are permutations of the holes (eq. 6), fitness the inverse path length (eq. 7).

One generation, as we read Figure 4 and Table 2 (the paper gives no pseudo-code):

1. **Tournament selection**: ``population`` parents, each the shortest of ``tournament``
   individuals drawn at random (O(N) per generation, Table 2).
2. **Greedy heuristic crossover** (Grefenstette's greedy crossover) on consecutive parent
   pairs with probability ``crossover``: child k starts with parent k's first hole; from the
   current hole it goes to the nearer of that hole's successors in the two parents, and
   when both are already drilled, to the nearest undrilled hole. Vectorised over all children.
3. **Mutation** with probability ``mutation`` per child: swap two holes (0.2), reverse a
   stretch (0.5) or move one hole elsewhere (0.3).
4. **Simulated annealing with large-neighbourhood search** on the whole new population
   (Table 2's extra ``O(G N C)``: one neighbour per individual per generation): ruin and
   recreate, i.e. remove ``destroy_fraction`` of the holes and put each back at its cheapest
   position; the removed holes are random ones for half the individuals and a random hole
   with its nearest neighbours (Shaw's related removal: a region is rebuilt) for the other
   half (``removal="mixed"``). The neighbour replaces the individual if shorter, or with
   probability ``exp(-delta / T)``. ``T`` starts at ``initial_temperature`` (default: the
   mean nearest-neighbour distance of the face) and is multiplied by ``cooling`` each
   generation.
5. **Elitism**: the best path found so far replaces the worst individual.

The initial population is random, as in the paper; nothing else (no 2-opt, no greedy
seeding) is added, so the comparison with ACO and AGA is the paper's.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import SequencingProblem, bad_param
from .iterative import Budget, IterativeSequencer

__all__ = ["IGA", "greedy_crossover", "ruin_and_recreate"]


@dataclass(frozen=True)
class IGA(IterativeSequencer):
    """IGA parameters (defaults: paper 002, section 4.1; ``tournament``, ``destroy_fraction``,
    ``removal`` and ``initial_temperature`` are not printed and are ours, tuned on faces of
    40-52 holes)."""

    name = "iga"

    population: int = field(default=50, metadata={"ge": 2, "le": 500, "description": "even"})
    crossover: float = field(default=0.95, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    mutation: float = field(default=0.05, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    iterations: int = field(default=400, metadata={"ge": 1, "le": 5000})
    p_swap: float = field(default=0.2, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    p_reverse: float = field(default=0.5, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    p_insert: float = field(default=0.3, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    cooling: float = field(default=0.99, metadata={"gt": 0.0, "le": 1.0})
    tournament: int = field(default=2, metadata={"ge": 1, "le": 500})
    destroy_fraction: float = field(default=0.3, metadata={"ge": 0.0, "le": 1.0})
    removal: str = field(default="mixed", metadata={"choices": ("random", "related", "mixed")})
    initial_temperature: float | None = field(default=None, metadata={
        "gt": 0.0, "le": 1e7, "description": "mm; default the mean nearest-neighbour distance"})

    def __post_init__(self) -> None:
        if self.population < 2 or self.population % 2:
            raise bad_param("population", "must be an even number >= 2")
        for name in ("crossover", "mutation", "p_swap", "p_reverse", "p_insert",
                     "destroy_fraction"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise bad_param(name, f"must be in [0, 1], got {v}")
        if abs(self.p_swap + self.p_reverse + self.p_insert - 1.0) > 1e-9:
            raise bad_param("p_swap", "p_swap + p_reverse + p_insert must be 1")
        if not 0.0 < self.cooling <= 1.0:
            raise bad_param("cooling", f"must be in (0, 1], got {self.cooling}")
        if self.iterations < 1:
            raise bad_param("iterations", "must be >= 1")
        if not 1 <= self.tournament <= self.population:
            raise bad_param("tournament", "must be between 1 and the population")
        if self.removal not in ("random", "related", "mixed"):
            raise bad_param("removal", "must be 'random', 'related' or 'mixed'")
        if self.initial_temperature is not None and not self.initial_temperature > 0:
            raise bad_param("initial_temperature", "must be positive")

    def _body(self, problem: SequencingProblem, rng: np.random.Generator,
              tr: Budget) -> str:
        n, P = problem.n, self.population
        pop = rng.random((P, n)).argsort(axis=1)
        fit = tr.evaluate(pop)
        T = self.initial_temperature or problem.nn_distance
        k_destroy = max(2, min(n - 1, round(self.destroy_fraction * n)))
        for _ in range(self.iterations):
            # 1. tournament selection
            entrants = rng.integers(0, P, size=(P, self.tournament))
            winners = entrants[np.arange(P), np.argmin(fit[entrants], axis=1)]
            parents = pop[winners]
            # 2. greedy heuristic crossover on pairs (0,1), (2,3), ...
            children = parents.copy()
            cross = np.flatnonzero(rng.random(P // 2) < self.crossover)
            if len(cross):
                a, b = parents[2 * cross], parents[2 * cross + 1]
                children[2 * cross] = greedy_crossover(problem, a, b)
                children[2 * cross + 1] = greedy_crossover(problem, b, a)
            # 3. mutation
            for i in np.flatnonzero(rng.random(P) < self.mutation):
                children[i] = self._mutate(children[i], rng)
            child_fit = tr.evaluate(children)
            # 4. simulated annealing over a large neighbourhood (ruin and recreate)
            neigh = ruin_and_recreate(problem, children, k_destroy, rng, self.removal)
            neigh_fit = tr.evaluate(neigh)
            delta = neigh_fit - child_fit
            accept = (delta < 0) | (rng.random(P) < np.exp(-np.maximum(delta, 0) / T))
            children[accept] = neigh[accept]
            child_fit[accept] = neigh_fit[accept]
            T *= self.cooling
            # 5. elitism
            worst = int(np.argmax(child_fit))
            if tr.best_value < child_fit[worst]:
                children[worst] = tr.best
                child_fit[worst] = tr.best_value
            pop, fit = children, child_fit
            tr.end_iteration()
        return f"{self.iterations} generations"

    def _mutate(self, order: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        n = len(order)
        i, j = sorted(rng.choice(n, size=2, replace=False))
        u = rng.random()
        out = order.copy()
        if u < self.p_swap:
            out[i], out[j] = out[j], out[i]
        elif u < self.p_swap + self.p_reverse:
            out[i : j + 1] = out[i : j + 1][::-1]
        else:  # insertion: move the hole at i to position j
            out = np.insert(np.delete(out, i), j, order[i])
        return out


def _successors(orders: np.ndarray) -> np.ndarray:
    """``succ[b, v]`` = the hole after ``v`` in ``orders[b]`` (-1 after the last). ``(B, n)``."""
    B, n = orders.shape
    succ = np.full((B, n), -1, dtype=int)
    rows = np.arange(B)[:, None]
    succ[rows, orders[:, :-1]] = orders[:, 1:]
    return succ


def greedy_crossover(problem: SequencingProblem, first: np.ndarray,
                     second: np.ndarray) -> np.ndarray:
    """Greedy heuristic crossover of parent pairs ``first, second (B, n) -> children (B, n)``.

    Each child starts with ``first``'s first hole and then goes to the nearer of the current
    hole's successors in both parents; if both are drilled already, to the nearest undrilled
    hole (the greedy fallback). Edges the parents share are kept; the rest is chosen greedily.
    """
    B, n = first.shape
    D = problem.D
    s1, s2 = _successors(first), _successors(second)
    rows = np.arange(B)
    seen = np.zeros((B, n), dtype=bool)
    child = np.empty((B, n), dtype=int)
    cur = first[:, 0].copy()
    child[:, 0] = cur
    seen[rows, cur] = True
    for t in range(1, n):
        c1, c2 = s1[rows, cur], s2[rows, cur]
        ok1 = (c1 >= 0) & ~seen[rows, np.maximum(c1, 0)]
        ok2 = (c2 >= 0) & ~seen[rows, np.maximum(c2, 0)]
        d1 = np.where(ok1, D[cur, np.maximum(c1, 0)], np.inf)
        d2 = np.where(ok2, D[cur, np.maximum(c2, 0)], np.inf)
        nxt = np.where(d1 <= d2, c1, c2)
        stuck = np.flatnonzero(~ok1 & ~ok2)
        if len(stuck):
            dist = np.where(seen[stuck], np.inf, D[cur[stuck]])
            nxt[stuck] = np.argmin(dist, axis=1)
        child[:, t] = nxt
        seen[rows, nxt] = True
        cur = nxt
    return child


def ruin_and_recreate(problem: SequencingProblem, orders: np.ndarray, k: int,
                      rng: np.random.Generator, removal: str = "related") -> np.ndarray:
    """Large-neighbourhood move for every row of ``orders (B, n)``: remove ``k`` holes and
    reinsert them one by one (in random order) where each lengthens the open path least.
    ``removal``: ``"random"`` holes, ``"related"`` ones (a random hole and its ``k - 1``
    nearest neighbours, Shaw's removal: a region is rebuilt) or ``"mixed"`` (each row one or
    the other at random). Vectorised over the batch; ``(B, n) -> (B, n)``."""
    B, n = orders.shape
    E = problem.E
    rows = np.arange(B)[:, None]
    pos = np.empty((B, n), dtype=int)
    pos[rows, orders] = np.arange(n)[None, :]
    holes_random = rng.random((B, n)).argsort(axis=1)[:, :k]
    seed_hole = rng.integers(0, n, size=B)
    near = np.argsort(problem.D[seed_hole], axis=1, kind="stable")[:, :k]  # includes itself
    near = near[rows, rng.random((B, k)).argsort(axis=1)]  # reinsert in random order
    use_related = np.full(B, removal == "related") if removal != "mixed" else \
        rng.random(B) < 0.5
    removed = np.where(use_related[:, None], near, holes_random)  # (B, k) hole ids
    removed_mask = np.zeros((B, n), dtype=bool)
    removed_mask[rows, pos[rows, removed]] = True
    kept = orders[~removed_mask].reshape(B, n - k)
    start = np.full((B, 1), n)
    end = np.full((B, 1), n + 1)
    r = np.arange(B)
    for c in range(k):
        v = removed[:, c]
        m = kept.shape[1]
        ext = np.concatenate([start, kept, end], axis=1)  # (B, m+2)
        a, b = ext[:, :-1], ext[:, 1:]  # the m+1 edges
        cost = E[a, v[:, None]] + E[v[:, None], b] - E[a, b]
        pos = np.argmin(cost, axis=1)  # insert before kept[:, pos]
        idx = np.arange(m + 1)[None, :]
        src = np.where(idx < pos[:, None], idx, idx - 1)
        new = kept[r[:, None], np.clip(src, 0, max(m - 1, 0))] if m else \
            np.empty((B, 1), dtype=int)
        new = np.where(idx == pos[:, None], v[:, None], new)
        kept = new
    return kept
