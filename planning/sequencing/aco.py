"""Ant colony optimisation (Ant System) for hole sequencing: the paper's first baseline.

Paper 002, section 4.1 (its ref. [27]): pheromone weight ``alpha = 1``, heuristic weight
``beta = 3``, evaporation ``rho = 0.5``, 50 ants, deposit ``Q = 1``, 400 iterations. This is
Dorigo's Ant System adapted to the open path: every ant starts at the arm's start position
and moves to an undrilled hole ``j`` with probability proportional to
``tau[i, j]^alpha * (1 / d[i, j])^beta``; after all ants have built their paths, the
pheromone evaporates (``tau <- (1 - rho) tau``) and each ant deposits ``Q / L_k`` on every
edge of its path (both directions between holes). The initial pheromone is ``m / L_nn``
(Dorigo and Stützle's recommendation for the Ant System, ``L_nn`` = the nearest-neighbour
path length). All ants advance together, one vectorised step per hole.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import SequencingProblem, bad_param
from .iterative import Budget, IterativeSequencer
from .local import nearest_neighbour

__all__ = ["ACO"]


@dataclass(frozen=True)
class ACO(IterativeSequencer):
    """Ant System parameters (defaults: paper 002, section 4.1)."""

    name = "aco"

    ants: int = field(default=50, metadata={"ge": 1, "le": 500})
    alpha: float = field(default=1.0, metadata={"ge": 0.0, "le": 20.0})
    beta: float = field(default=3.0, metadata={"ge": 0.0, "le": 20.0})
    rho: float = field(default=0.5, metadata={"gt": 0.0, "le": 1.0})
    q: float = field(default=1.0, metadata={"gt": 0.0, "le": 1e9})
    iterations: int = field(default=400, metadata={"ge": 1, "le": 5000})

    def __post_init__(self) -> None:
        if self.ants < 1:
            raise bad_param("ants", "must be >= 1")
        if not 0.0 < self.rho <= 1.0:
            raise bad_param("rho", f"must be in (0, 1], got {self.rho}")
        for name in ("alpha", "beta"):
            if getattr(self, name) < 0:
                raise bad_param(name, "must be >= 0")
        if not self.q > 0:
            raise bad_param("q", "must be positive")
        if self.iterations < 1:
            raise bad_param("iterations", "must be >= 1")

    def _body(self, problem: SequencingProblem, rng: np.random.Generator, tr: Budget) -> str:
        n, m = problem.n, self.ants
        # Rows 0..n-1: from a hole; row n: from the start. Columns: to a hole.
        dist = np.vstack([problem.D, problem.d0[None, :]])
        with np.errstate(divide="ignore"):
            eta = np.where(dist > 0, 1.0 / np.where(dist > 0, dist, 1.0), 0.0) ** self.beta
        L_nn = problem.length(nearest_neighbour(problem))
        tau = np.full((n + 1, n), m / L_nn)
        ants = np.arange(m)
        for _ in range(self.iterations):
            weight = tau**self.alpha * eta
            seen = np.zeros((m, n), dtype=bool)
            paths = np.empty((m, n), dtype=int)
            cur = np.full(m, n)
            for t in range(n):
                w = np.where(seen, 0.0, weight[cur])
                cum = np.cumsum(w, axis=1)
                total = cum[:, -1]
                r = rng.random(m) * total
                nxt = np.minimum((cum <= r[:, None]).sum(axis=1), n - 1)
                # A row of zero weights (all heuristics underflowed) picks any undrilled hole.
                dead = ~(total > 0)
                if dead.any():
                    nxt[dead] = np.argmin(seen[dead], axis=1)
                # Guard against landing on a drilled hole through round-off at the top end.
                clash = seen[ants, nxt]
                if clash.any():
                    nxt[clash] = np.argmax(np.where(seen[clash], -1.0, w[clash]), axis=1)
                paths[:, t] = nxt
                seen[ants, nxt] = True
                cur = nxt
            L = tr.evaluate(paths)
            tau *= 1.0 - self.rho
            dep = np.broadcast_to((self.q / L)[:, None], (m, n - 1)).ravel()
            a, b = paths[:, :-1].ravel(), paths[:, 1:].ravel()
            np.add.at(tau, (a, b), dep)
            np.add.at(tau, (b, a), dep)
            np.add.at(tau, (np.full(m, n), paths[:, 0]), self.q / L)
            tr.end_iteration()
        return f"{self.iterations} iterations"
