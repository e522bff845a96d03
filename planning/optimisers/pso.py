"""Particle swarm optimisation with linearly decreasing inertia (paper 003 Table 2).

Global-best PSO (Kennedy and Eberhart 1995) with the inertia weight of Shi and Eberhart
(1998) falling linearly from ``w_start = 0.9`` to ``w_end = 0.4`` over the iterations::

    v <- w v + c1 r1 (p_best - x) + c2 r2 (g_best - x),   x <- clip(x + v)

with ``c1 = c2 = 2`` and ``r1, r2 ~ U(0, 1)`` per coordinate. Table 2 prints no velocity
clamp; with ``c1 + c2 = 4`` the swarm diverges without one, so ``|v|`` is clamped to
``v_max_fraction`` (0.2) of the box width per coordinate, the usual choice. Initial velocities
are uniform in ``[-v_max, v_max]``. Each iteration costs ``N`` evaluations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["PSO"]


@dataclass(frozen=True)
class PSO(Optimiser):
    """Linearly-decreasing-inertia PSO; defaults = paper 003 Table 2."""

    n_particles: int = field(default=50, metadata={"ge": 2, "le": 2000})  # N
    w_start: float = field(default=0.9, metadata={"ge": 0.0, "le": 2.0})
    w_end: float = field(default=0.4, metadata={"ge": 0.0, "le": 2.0})
    c1: float = field(default=2.0, metadata={
        "ge": 0.0, "le": 10.0})  # towards the particle's own best
    c2: float = field(default=2.0, metadata={"ge": 0.0, "le": 10.0})  # towards the swarm's best
    iterations: int = field(default=50, metadata={"ge": 1, "le": 10_000})  # Nc
    v_max_fraction: float = field(default=0.2, metadata={
        "gt": 0.0, "le": 1.0, "description": "fraction of the box width"})

    name = "pso"

    def __post_init__(self) -> None:
        if self.n_particles < 2:
            raise ValueError("n_particles: must be at least 2")
        if self.iterations < 1:
            raise ValueError("iterations: must be at least 1")
        for name in ("c1", "c2", "w_start", "w_end"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name}: must be >= 0")
        if not 0 < self.v_max_fraction <= 1:
            raise ValueError("v_max_fraction: must be in (0, 1]")

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, D = self.n_particles, pb.dim
        T = self.iterations if ev.max_evaluations is None else \
            min(self.iterations, max(1, ev.max_evaluations // N - 1))
        v_max = self.v_max_fraction * (np.asarray(pb.upper, float) - np.asarray(pb.lower, float))
        X = pb.uniform(rng, N)
        V = rng.uniform(-v_max, v_max, size=(N, D))
        F = ev.evaluate(X)
        P, FP = X.copy(), F.copy()
        for t in range(T):
            w = self.w_start - (self.w_start - self.w_end) * t / max(T - 1, 1)
            g = P[np.argmin(FP)]
            r1, r2 = rng.random((N, D)), rng.random((N, D))
            V = np.clip(w * V + self.c1 * r1 * (P - X) + self.c2 * r2 * (g - X), -v_max, v_max)
            X = pb.clip(X + V)
            F = ev.evaluate(X)
            better = F < FP
            P[better], FP[better] = X[better], F[better]
            ev.end_iteration()
        return f"{T} iterations"
