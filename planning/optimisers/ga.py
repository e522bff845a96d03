"""A generic real-coded genetic algorithm (the "basic GA" baseline of papers 000 and 003).

Each generation: the best ``elite`` individuals pass unchanged; the best ``selection``
fraction of the population forms the parent pool (truncation selection); pairs of random
parents give a child by BLX-0.5 blend crossover with probability ``crossover`` (else a copy
of the first parent); a child is mutated with probability ``mutation`` by Gaussian noise of
standard deviation ``mutation_scale * (upper - lower)`` (shrinking linearly to a tenth over
the run) on each gene with probability ``1/D`` (at least one gene). Children are clipped to
the box.

Defaults (population 50, crossover 0.8, mutation 0.5, 50 iterations) are the PI-gain tuning
setting; ``GeneticAlgorithm.paper_000()`` is paper 000's path-planning GA: population 5,
crossover 0.8, selection 0.5, mutation 0.2 (its chromosome length 5 is the number of path
waypoints, a property of the encoding: ``paths.DEFAULT_WAYPOINTS``). The paper prints no
iteration count for it; we use 100, as for its ant colony and fish swarm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["GeneticAlgorithm"]


@dataclass(frozen=True)
class GeneticAlgorithm(Optimiser):
    """Real-coded GA; every rate is a probability in [0, 1]."""

    population: int = field(default=50, metadata={"ge": 2, "le": 2000})
    crossover: float = field(default=0.8, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    selection: float = field(default=0.5, metadata={
        "gt": 0.0, "le": 1.0, "description": "fraction of parents"})
    mutation: float = field(default=0.5, metadata={
        "ge": 0.0, "le": 1.0, "description": "probability"})
    iterations: int = field(default=50, metadata={"ge": 1, "le": 20_000})
    mutation_scale: float = field(default=0.1, metadata={
        "gt": 0.0, "le": 10.0, "description": "fraction of the range"})
    elite: int = field(default=1, metadata={"ge": 0, "le": 1999})

    name = "ga"

    def __post_init__(self) -> None:
        if self.population < 2:
            raise ValueError("population must be at least 2")
        if self.iterations < 1:
            raise ValueError("iterations must be at least 1")
        for name in ("crossover", "selection", "mutation"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1]")
        if not self.selection > 0:
            raise ValueError("selection must be positive")
        if not self.mutation_scale > 0:
            raise ValueError("mutation_scale must be positive")
        if not 0 <= self.elite < self.population:
            raise ValueError("elite must be in [0, population)")

    @classmethod
    def paper_000(cls) -> GeneticAlgorithm:
        """Paper 000's path-planning GA (section 4.3)."""
        return cls(population=5, crossover=0.8, selection=0.5, mutation=0.2, iterations=100)

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        P, D = self.population, pb.dim
        span = np.asarray(pb.upper, float) - np.asarray(pb.lower, float)
        X = pb.uniform(rng, P)
        F = ev.evaluate(X)
        n_parents = max(2, math.ceil(self.selection * P))
        n_children = P - self.elite
        for it in range(self.iterations):
            order = np.argsort(F, kind="stable")
            X, F = X[order], F[order]
            pool = X[:n_parents]
            a = pool[rng.integers(0, n_parents, n_children)]
            b = pool[rng.integers(0, n_parents, n_children)]
            u = rng.uniform(-0.5, 1.5, size=(n_children, D))
            cross = rng.random(n_children) < self.crossover
            child = np.where(cross[:, None], a + u * (b - a), a)
            mutate = rng.random(n_children) < self.mutation
            genes = rng.random((n_children, D)) < 1.0 / D
            genes[np.arange(n_children), rng.integers(0, D, n_children)] = True
            sigma = self.mutation_scale * span * (1.0 - 0.9 * it / self.iterations)
            noise = rng.normal(0.0, 1.0, size=(n_children, D)) * sigma
            child = pb.clip(child + np.where(mutate[:, None] & genes, noise, 0.0))
            FC = ev.evaluate(child)
            X = np.vstack([X[: self.elite], child])
            F = np.concatenate([F[: self.elite], FC])
            ev.end_iteration()
        return f"{self.iterations} generations"
