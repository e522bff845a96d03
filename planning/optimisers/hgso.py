"""Henry gas solubility optimisation (HGSO): paper 003 eqs. 14-22, Table 2.

HGSO (Hashim, Houssein, Mabrouk, Al-Atabany and Mirjalili, "Henry gas solubility
optimization: a novel physics-based algorithm", Future Gener. Comput. Syst. 101 (2019)
646-667) moves ``N`` gas particles split into ``M`` type clusters. Per cluster ``j``:
Henry's coefficient ``H_j``, van't Hoff constant ``C_j``; per gas ``i``: partial pressure
``P_i``. One iteration ``t`` of ``T``:

1. Eq. 19: ``H_j <- H_j exp(-C_j (1/T(t) - 1/T_ref))``, ``T(t) = exp(-t/T)``,
   ``T_ref = 298.15``.
2. Eq. 20: solubility ``S_i = K H_j P_i`` for gas ``i`` of cluster ``j`` (K = 1).
3. Eq. 21: ``X_i <- X_i + F r1 gamma_i (X_j,best - X_i) + F r2 alpha (S_i X_best - X_i)`` with
   ``gamma_i = beta exp(-(F_best + eps) / (F_i + eps))``, ``eps = 0.05``, ``F = +-1`` drawn per
   gas (direction flag), ``r1, r2 ~ U(0, 1)`` per coordinate, ``X_j,best`` the best gas of the
   cluster now, ``X_best`` / ``F_best`` the best gas found so far.
4. Eq. 22: the ``N_w = round(N (c1 + r (c2 - c1)))`` worst gases are re-drawn uniformly in the
   box (Hashim et al.'s eq. 11, the escape from local optima).

Initialisation (eqs. 17-18): ``X`` uniform in the box, ``H_j = l1 r``, ``P_i = l2 r``,
``C_j = l3 r``; gases go to clusters in equal contiguous blocks (``N / M`` each).

Readings where the seed is terse, following Hashim et al. (and their reference MATLAB code):
``X_best`` is the best-so-far gas; positions are clipped to the box after each move; the
seed's Algorithm 1 evaluates the population once per iteration, so the worst gases are
chosen by this iteration's fitness and re-drawn *instead of* being moved by eq. 21 -- each
iteration then costs exactly ``N`` evaluations (the original's second evaluation of the
reset gases is folded into the next iteration). The seed's Table 2 / text values are the
defaults (``l1 = 5e-2``; the original paper printed 5e-3). ``gamma`` assumes a non-negative
fitness (errors, norms), as in both papers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["HGSO"]


@dataclass(frozen=True)
class HGSO(Optimiser):
    """Henry gas solubility optimisation; defaults = paper 003 Table 2 and section 3.1."""

    n_gases: int = field(default=50, metadata={"ge": 2, "le": 2000})  # N
    n_clusters: int = field(default=5, metadata={"ge": 1, "le": 2000})  # M
    alpha: float = field(default=1.0, metadata={
        "gt": 0.0, "le": 100.0})  # influence of the other gases
    beta: float = field(default=1.0, metadata={
        "gt": 0.0, "le": 100.0})  # interaction-ability constant
    iterations: int = field(default=50, metadata={"ge": 1, "le": 10_000})  # Nc
    l1: float = field(default=5e-2, metadata={"gt": 0.0, "le": 1e3})
    l2: float = field(default=100.0, metadata={"gt": 0.0, "le": 1e6})
    l3: float = field(default=1e-2, metadata={"gt": 0.0, "le": 1e3})
    c1: float = field(default=0.1, metadata={"ge": 0.0, "lt": 1.0})  # worst-gas fraction, low
    c2: float = field(default=0.2, metadata={"ge": 0.0, "lt": 1.0})  # worst-gas fraction, high
    K: float = field(default=1.0, metadata={"gt": 0.0, "le": 1e3})
    epsilon: float = field(default=0.05, metadata={"gt": 0.0, "le": 1.0})
    T_ref: float = field(default=298.15, metadata={"gt": 0.0, "le": 1e4, "description": "K"})

    name = "hgso"

    def __post_init__(self) -> None:
        if self.n_gases < 2:
            raise ValueError("n_gases: must be at least 2")
        if not 1 <= self.n_clusters <= self.n_gases:
            raise ValueError("n_clusters: must be in [1, n_gases]")
        if self.iterations < 1:
            raise ValueError("iterations: must be at least 1")
        for name in ("alpha", "beta", "l1", "l2", "l3", "K", "epsilon", "T_ref"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be positive")
        if not 0 <= self.c1 <= self.c2 < 1:
            raise ValueError("c1, c2: need 0 <= c1 <= c2 < 1")

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, M = self.n_gases, self.n_clusters
        T = self.iterations if ev.max_evaluations is None else \
            min(self.iterations, max(1, ev.max_evaluations // N - 1))
        cluster = np.arange(N) * M // N  # equal contiguous blocks
        members = [np.flatnonzero(cluster == j) for j in range(M)]
        # Eqs. 17-18.
        X = pb.uniform(rng, N)
        H = self.l1 * rng.random(M)
        P = self.l2 * rng.random(N)
        C = self.l3 * rng.random(M)
        F = ev.evaluate(X)
        for t in range(1, T + 1):
            x_best, f_best = ev.best, ev.best_value
            X_cluster_best = np.empty((M, pb.dim))
            for j, idx in enumerate(members):
                X_cluster_best[j] = X[idx[np.argmin(F[idx])]]
            temperature = np.exp(-t / T)
            H = H * np.exp(-C * (1.0 / temperature - 1.0 / self.T_ref))  # eq. 19
            S = self.K * H[cluster] * P  # eq. 20
            gamma = self.beta * np.exp(-(f_best + self.epsilon) / (F + self.epsilon))
            flag = rng.choice((-1.0, 1.0), size=(N, 1))
            r1, r2 = rng.random((N, pb.dim)), rng.random((N, pb.dim))
            X_new = (X + flag * r1 * gamma[:, None] * (X_cluster_best[cluster] - X)
                     + flag * r2 * self.alpha * (S[:, None] * x_best - X))  # eq. 21
            n_worst = int(round(N * (self.c1 + rng.random() * (self.c2 - self.c1))))  # eq. 22
            if n_worst:
                worst = np.argsort(F, kind="stable")[N - n_worst:]
                X_new[worst] = pb.uniform(rng, n_worst)
            X = pb.clip(X_new)
            F = ev.evaluate(X)
            ev.end_iteration()
        return f"{T} iterations"
