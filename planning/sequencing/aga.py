"""Adaptive genetic algorithm (AGA) for hole sequencing: the paper's second baseline.

Paper 002, section 4.1 (its ref. [28]) sets population 50, crossover 0.95, mutation 0.05 and
400 iterations for both IGA and AGA. The adaptive part is Srinivas and Patnaik's rule (IEEE
Trans. SMC 24(4), 1994), with the printed probabilities as the upper ends: a pair whose
fitter parent is at least average crosses with

    ``pc = pc_max - (pc_max - pc_min) (f' - f_avg) / (f_max - f_avg)``

(else ``pc_max``), and an individual at least average mutates with the same rule on
``pm``; fitness is ``1 / length``. So the best individuals are disturbed least. The rest is a
textbook permutation GA: roulette-wheel selection (on windowed fitness ``L_max - L``, plus
5 % of the spread so the worst keeps a chance), order crossover (OX), inversion mutation
(reverse a random stretch) and one elite. ``pc_min`` and ``pm_min`` are not printed (ours).
Without any local search it ends far above IGA on our faces (about +45-55 % after 400
generations, ``benchmarks/bench_sequencing.py``), not the paper's +7 %: the paper does not
describe its AGA beyond the reference.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import SequencingProblem, bad_param
from .iterative import Budget, IterativeSequencer

__all__ = ["AGA", "order_crossover"]


@dataclass(frozen=True)
class AGA(IterativeSequencer):
    """AGA parameters (defaults: paper 002 section 4.1, plus our ``pc_min``, ``pm_min``)."""

    name = "aga"

    population: int = field(default=50, metadata={"ge": 2, "le": 1000, "description": "even"})
    crossover: float = field(default=0.95, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    mutation: float = field(default=0.05, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    iterations: int = field(default=400, metadata={"ge": 1, "le": 20_000})
    crossover_min: float = field(default=0.6, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    mutation_min: float = field(default=0.01, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})

    def __post_init__(self) -> None:
        if self.population < 2 or self.population % 2:
            raise bad_param("population", "must be an even number >= 2")
        for name in ("crossover", "mutation", "crossover_min", "mutation_min"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise bad_param(name, f"must be in [0, 1], got {v}")
        if self.crossover_min > self.crossover:
            raise bad_param("crossover_min", "must not exceed crossover")
        if self.mutation_min > self.mutation:
            raise bad_param("mutation_min", "must not exceed mutation")
        if self.iterations < 1:
            raise bad_param("iterations", "must be >= 1")

    def _adaptive(self, f: np.ndarray, f_avg: float, f_max: float, hi: float,
                  lo: float) -> np.ndarray:
        span = max(f_max - f_avg, 1e-300)
        return np.where(f >= f_avg, hi - (hi - lo) * (f - f_avg) / span, hi)

    def _body(self, problem: SequencingProblem, rng: np.random.Generator, tr: Budget) -> str:
        n, P = problem.n, self.population
        pop = rng.random((P, n)).argsort(axis=1)
        L = tr.evaluate(pop)
        for _ in range(self.iterations):
            f = 1.0 / L
            f_avg, f_max = float(f.mean()), float(f.max())
            # roulette wheel on windowed fitness (the worst gets a small share)
            w = (L.max() - L) + 0.05 * max(L.max() - L.min(), 1e-9)
            parents_idx = rng.choice(P, size=P, p=w / w.sum())
            parents, pf = pop[parents_idx], f[parents_idx]
            children = parents.copy()
            pair_f = np.maximum(pf[0::2], pf[1::2])
            pc = self._adaptive(pair_f, f_avg, f_max, self.crossover, self.crossover_min)
            for k in np.flatnonzero(rng.random(P // 2) < pc):
                a, b = parents[2 * k], parents[2 * k + 1]
                i, j = sorted(rng.choice(n, size=2, replace=False))
                children[2 * k] = order_crossover(a, b, i, j)
                children[2 * k + 1] = order_crossover(b, a, i, j)
            pm = self._adaptive(pf, f_avg, f_max, self.mutation, self.mutation_min)
            for k in np.flatnonzero(rng.random(P) < pm):
                i, j = sorted(rng.choice(n, size=2, replace=False))
                children[k, i : j + 1] = children[k, i : j + 1][::-1]
            child_L = tr.evaluate(children)
            worst = int(np.argmax(child_L))
            if tr.best_value < child_L[worst]:
                children[worst] = tr.best
                child_L[worst] = tr.best_value
            pop, L = children, child_L
            tr.end_iteration()
        return f"{self.iterations} generations"


def order_crossover(a: np.ndarray, b: np.ndarray, i: int, j: int) -> np.ndarray:
    """OX: keep ``a[i..j]`` in place, fill the other positions (from ``j+1``, wrapping) with
    ``b``'s remaining holes in ``b``'s order (from ``j+1``, wrapping). ``(n,)``."""
    n = len(a)
    child = np.empty(n, dtype=int)
    child[i : j + 1] = a[i : j + 1]
    keep = np.zeros(n, dtype=bool)
    keep[a[i : j + 1]] = True
    rot = np.roll(b, -(j + 1))
    fill = rot[~keep[rot]]
    pos = (np.arange(j + 1, j + 1 + len(fill))) % n
    child[pos] = fill
    return child
