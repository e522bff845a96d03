"""Adaptive genetic algorithm (AGA) for hole sequencing: the paper's second baseline.

Paper 002, section 4.1 (its ref. [28]) sets population 50, crossover 0.95, mutation 0.05 and
400 iterations for both IGA and AGA, and describes its AGA no further. The adaptive part is
Srinivas and Patnaik's rule (IEEE Trans. SMC 24(4), 656-667, 1994), with fitness
``f = 1 / length`` (eq. 7), ``f_max`` and ``f_avg`` the population's best and mean:

    pc = k1 (f_max - f') / (f_max - f_avg)   if f' >= f_avg,   else k3
    pm = k2 (f_max - f)  / (f_max - f_avg)   if f  >= f_avg,   else k4

``f'`` is the fitter parent of a pair and ``f`` the individual's own fitness. Srinivas and
Patnaik use k1 = k3 = 1.0 and k2 = k4 = 0.5; the paper prints 0.95 and 0.05, which we take as
k1 = k3 (``crossover``) and k2 = k4 (``mutation``): below-average individuals get the printed
probabilities, and the better an individual the less it is disturbed, the best not at all.
Srinivas and Patnaik add a small default mutation rate for every individual so the best ones
do not stagnate (0.005 in their experiments): ``mutation_min``; ``crossover_min`` (default 0)
is the same floor for crossover.

The rest is a textbook permutation GA, as a GA without a local search step is what the paper
improves on: roulette-wheel selection on windowed fitness (``L_max - L``, plus 5 % of the
spread so the worst keeps a chance; ours: raw ``1 / L`` gives almost uniform selection on a
face whose paths differ by tens of percent), order crossover (OX), inversion mutation
(reverse a random stretch: the 2-opt move) and one elite (Srinivas and Patnaik keep the best
through ``pc = pm = 0``; the elite makes that explicit). The initial population is random.
``benchmarks/bench_papers.py`` prints how far it ends above IGA next to the paper's 7 %.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import SequencingProblem, bad_param
from .iterative import Budget, IterativeSequencer

__all__ = ["AGA", "adaptive_probability", "order_crossover"]


@dataclass(frozen=True)
class AGA(IterativeSequencer):
    """AGA parameters (defaults: paper 002 section 4.1 for ``crossover`` = k1 = k3 and
    ``mutation`` = k2 = k4; Srinivas and Patnaik's default mutation rate 0.005 for
    ``mutation_min``; ``crossover_min`` ours)."""

    name = "aga"

    population: int = field(default=50, metadata={"ge": 2, "le": 1000, "description": "even"})
    crossover: float = field(default=0.95, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    mutation: float = field(default=0.05, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    iterations: int = field(default=400, metadata={"ge": 1, "le": 20_000})
    crossover_min: float = field(default=0.0, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    mutation_min: float = field(default=0.005, metadata={
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
            pc = np.maximum(adaptive_probability(pair_f, f_avg, f_max, self.crossover),
                            self.crossover_min)
            for k in np.flatnonzero(rng.random(P // 2) < pc):
                a, b = parents[2 * k], parents[2 * k + 1]
                i, j = sorted(rng.choice(n, size=2, replace=False))
                children[2 * k] = order_crossover(a, b, i, j)
                children[2 * k + 1] = order_crossover(b, a, i, j)
            pm = np.maximum(adaptive_probability(pf, f_avg, f_max, self.mutation),
                            self.mutation_min)
            # per gene, as Srinivas and Patnaik's per-bit rate: each hole starts an inversion
            # with probability pm (a stretch from it to a random other hole is reversed)
            for k in range(P):
                for i in np.flatnonzero(rng.random(n) < pm[k]):
                    a, b = sorted((int(i), int(rng.integers(n))))
                    children[k, a : b + 1] = children[k, a : b + 1][::-1]
            child_L = tr.evaluate(children)
            worst = int(np.argmax(child_L))
            if tr.best_value < child_L[worst]:
                children[worst] = tr.best
                child_L[worst] = tr.best_value
            pop, L = children, child_L
            tr.end_iteration()
        return f"{self.iterations} generations"


def adaptive_probability(f: np.ndarray, f_avg: float, f_max: float, k: float) -> np.ndarray:
    """Srinivas and Patnaik's adaptive probability for fitnesses ``f (B,)``:
    ``k (f_max - f) / (f_max - f_avg)`` at or above the average, ``k`` below it (so ``k`` at
    the average, 0 at the best). A population of equal fitness (``f_max = f_avg``) gives 0
    to all: nothing is better than anything else to protect or disturb. ``(B,)``."""
    f = np.asarray(f, dtype=float)
    span = f_max - f_avg
    if not span > 0:
        return np.zeros_like(f)
    return np.where(f >= f_avg, k * np.clip((f_max - f) / span, 0.0, 1.0), k)


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
