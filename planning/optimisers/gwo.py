"""Grey wolf optimiser (Mirjalili, Mirjalili and Lewis 2014), paper 003 Table 2.

The three best wolves found so far (alpha, beta, delta) lead; every wolf moves to the mean
of three points, one per leader ``L``::

    A = 2 a r1 - a,  C = 2 r2,  X_L = L - A |C L - x|,  x <- clip((X_alpha + X_beta + X_delta) / 3)

with ``r1, r2 ~ U(0, 1)`` per coordinate and ``a`` falling linearly from 2 to 0 over the
iterations (Table 2). The leaders are the best three distinct points ever evaluated (the
original's intent; its code replaces a leader without shifting the others). Each iteration
costs ``N`` evaluations. This is Mirjalili's GWO, not the wolf pack algorithm of
``wolfpack.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .base import Evaluator, Optimiser

__all__ = ["GWO"]


@dataclass(frozen=True)
class GWO(Optimiser):
    """Grey wolf optimiser; defaults = paper 003 Table 2."""

    n_wolves: int = 50  # N
    a_start: float = 2.0
    a_end: float = 0.0
    iterations: int = 50  # Nc

    name = "gwo"

    def __post_init__(self) -> None:
        if self.n_wolves < 3:
            raise ValueError("n_wolves: must be at least 3")
        if self.iterations < 1:
            raise ValueError("iterations: must be at least 1")
        if not self.a_start >= self.a_end >= 0:
            raise ValueError("a_start, a_end: need a_start >= a_end >= 0")


    def _run(self, ev: Evaluator, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, D = self.n_wolves, pb.dim
        T = self.iterations if ev.max_evaluations is None else \
            min(self.iterations, max(1, ev.max_evaluations // N - 1))
        X = pb.uniform(rng, N)
        F = ev.evaluate(X)
        order = np.argsort(F, kind="stable")[:3]
        leaders, f_leaders = X[order].copy(), F[order].copy()
        for t in range(T):
            a = self.a_start - (self.a_start - self.a_end) * t / T
            A = a * (2.0 * rng.random((3, N, D)) - 1.0)
            C = 2.0 * rng.random((3, N, D))
            L = leaders[:, None, :]
            X = pb.clip(np.mean(L - A * np.abs(C * L - X[None]), axis=0))
            F = ev.evaluate(X)
            pool_X = np.concatenate([leaders, X])
            pool_F = np.concatenate([f_leaders, F])
            order = np.argsort(pool_F, kind="stable")
            keep = [order[0]]
            for i in order[1:]:  # three distinct leaders
                if len(keep) == 3:
                    break
                if not any(np.array_equal(pool_X[i], pool_X[k]) for k in keep):
                    keep.append(i)
            while len(keep) < 3:
                keep.append(keep[-1])
            leaders, f_leaders = pool_X[keep].copy(), pool_F[keep].copy()
            ev.end_iteration()
        return f"{T} iterations"
