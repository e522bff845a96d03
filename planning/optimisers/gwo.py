"""Grey wolf optimiser (Mirjalili, Mirjalili and Lewis 2014), paper 003 Table 2.

The three best wolves found so far (alpha, beta, delta) lead; every wolf moves to the mean
of three points, one per leader ``L``::

    A = 2 a r1 - a,  C = 2 r2,  X_L = L - A |C L - x|,  x <- clip((X_alpha + X_beta + X_delta) / 3)

with ``r1, r2 ~ U(0, 1)`` per coordinate and ``a`` falling linearly from 2 to 0 over the
iterations (Table 2). The leaders are the best three distinct points ever evaluated (the
original's intent; its code replaces a leader without shifting the others). Each iteration
costs ``N`` evaluations. This is Mirjalili's GWO, not the wolf pack algorithm of
``wolfpack.py``.

The pack moves in groups of ``leader_refresh`` wolves and the leaders are refreshed after
each group (an asynchronous update: a wolf that finds a better point leads the next group at
once, where the original moves the whole pack on the leaders of the previous iteration;
``leader_refresh = n_wolves`` is that synchronous update). Groups of 5 out of 50 converge
markedly faster on smooth functions and are no worse on multimodal ones: in
``benchmarks/bench_optimisers.py`` the median over 30 seeds beats mealpy's ``OriginalGWO``
on sphere, Rastrigin, Rosenbrock and Ackley (D = 10, 2550 evaluations), where the
synchronous update lost on three of the four. The price is ``n_wolves / leader_refresh``
calls of the batched objective per iteration instead of one (the evaluations are the same):
where one call has a large fixed cost, as the tracking simulation has, a tuning run takes
about four times as long as with one batch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["GWO"]


@dataclass(frozen=True)
class GWO(Optimiser):
    """Grey wolf optimiser; defaults = paper 003 Table 2."""

    n_wolves: int = field(default=50, metadata={"ge": 3, "le": 1000})  # N
    a_start: float = field(default=2.0, metadata={"ge": 0.0, "le": 10.0})
    a_end: float = field(default=0.0, metadata={"ge": 0.0, "le": 10.0})
    iterations: int = field(default=50, metadata={"ge": 1, "le": 10_000})  # Nc
    leader_refresh: int = field(default=5, metadata={
        "ge": 1, "le": 1000})  # wolves moved between leader updates

    name = "gwo"

    def __post_init__(self) -> None:
        if self.n_wolves < 3:
            raise ValueError("n_wolves: must be at least 3")
        if self.iterations < 1:
            raise ValueError("iterations: must be at least 1")
        if not self.a_start >= self.a_end >= 0:
            raise ValueError("a_start, a_end: need a_start >= a_end >= 0")
        if not 1 <= self.leader_refresh <= self.n_wolves:
            raise ValueError("leader_refresh: must be between 1 and n_wolves")

    @staticmethod
    def _leaders(pool_X: np.ndarray, pool_F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The best three distinct points of a pool (repeated if fewer are distinct)."""
        order = np.argsort(pool_F, kind="stable")
        keep = [order[0]]
        for i in order[1:]:
            if len(keep) == 3:
                break
            if not any(np.array_equal(pool_X[i], pool_X[k]) for k in keep):
                keep.append(i)
        while len(keep) < 3:
            keep.append(keep[-1])
        return pool_X[keep].copy(), pool_F[keep].copy()

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, D = self.n_wolves, pb.dim
        T = self.iterations if ev.max_evaluations is None else \
            min(self.iterations, max(1, ev.max_evaluations // N - 1))
        X = pb.uniform(rng, N)
        F = ev.evaluate(X)
        leaders, f_leaders = self._leaders(X, F)
        groups = [np.arange(i, min(i + self.leader_refresh, N))
                  for i in range(0, N, self.leader_refresh)]
        for t in range(T):
            a = self.a_start - (self.a_start - self.a_end) * t / T
            for g in groups:
                n = len(g)
                A = a * (2.0 * rng.random((3, n, D)) - 1.0)
                C = 2.0 * rng.random((3, n, D))
                L = leaders[:, None, :]
                X[g] = pb.clip(np.mean(L - A * np.abs(C * L - X[g][None]), axis=0))
                F_g = ev.evaluate(X[g])
                leaders, f_leaders = self._leaders(np.concatenate([leaders, X[g]]),
                                                   np.concatenate([f_leaders, F_g]))
            ev.end_iteration()
        return f"{T} iterations"
