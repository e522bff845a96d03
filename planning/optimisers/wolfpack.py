"""The wolf pack algorithm of paper 000, section 4.1 (wandering, summoning, siege; eqs. 26-30).

The paper calls it the "grey wolf" algorithm, but what it describes (scout wolves that wander
in ``h`` directions, a howl that summons the pack, a siege around the lead wolf, the worst
wolves replaced each generation) is the wolf pack algorithm (WPA, Wu et al. 2013), not
Mirjalili's GWO. Its Table 2 gives the parameters, which are our defaults. One iteration:

1. The best wolf is the lead (alpha, position ``G``); the next-best ``S_num`` wolves are the
   scouts (the paper's "beta" wolves), the rest the ferocious wolves (its "delta" wolves).
2. Wandering (eq. 26): each scout tries ``h`` moves ``x + sin(2 pi p / h) step_s`` (p = 1..h)
   and takes the best if it improves on its position; repeated up to ``K_max`` walks, or
   until a scout beats the lead and becomes it.
3. Summoning (eq. 27): the ferocious wolves run at the lead, ``x + step_b sign(G - x)`` per
   coordinate; any that beats the lead becomes it (the others now run at the new lead); a
   wolf stops once within ``d_near`` of the lead (eq. 28).
4. Siege (eq. 29): every wolf but the lead tries ``x + lambda step_w |G - x|`` with
   ``lambda ~ U[-1, 1]`` per coordinate, kept only if better.
5. Renewal: the worst ``R`` wolves, ``R`` a random integer in ``[N / (2 beta), N / beta]``,
   are replaced by random wolves.

Our readings where the paper is ambiguous or garbled (documented once, here):

* **Scouts**: Table 2's alpha = 0.5 in the classic rule ``S_num in [N/(alpha+1), N/alpha]``
  gives 67..200 scouts in a pack of 100, which is impossible; we read alpha as the fraction of
  the pack that scouts: ``S_num = round(alpha N)`` = 50 (capped at N - 1).
* **Steps** (eq. 30, printed ``step_s = step_b / 2 = 2 step_w |M - m| / C``): we take the
  classic WPA walking step ``step_s^d = |max_d - min_d| / S`` (S = 100, Table 2's step
  factor), ``step_b = 2 step_s`` (eq. 30's first equality), and from its second equality with
  ``C = S`` the siege factor ``step_w = 1/2`` as a *dimensionless* number, which makes eq. 29
  (``step_w |G - x|``) a length in mm on any scene, as it is on the paper's 100 mm one.
* **d_near** (eq. 28) is the mean range over ``omega``; we compare it with the Euclidean
  distance of a wolf to the lead. Summoning also stops after ``max_summon_steps`` steps
  (our cap: with per-coordinate sign steps a wolf can oscillate about the lead forever).
* Table 2's ``T_max = 50`` is the number of iterations and ``K_max = 10`` the number of
  walks (the text names the walk cap ``T_max`` too). Table 2's ``PC = 0.6`` (selection
  probability) has no role in the algorithm as described and is not used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["WolfPack"]


@dataclass(frozen=True)
class WolfPack(Optimiser):
    """Basic wolf pack algorithm; defaults = paper 000 Table 2."""

    n_wolves: int = field(default=100, metadata={"ge": 3, "le": 1000})  # N
    scout_fraction: float = field(default=0.5, metadata={
        "gt": 0.0, "lt": 1.0})  # alpha, read as the fraction of scouts
    step_factor: float = field(default=100.0, metadata={"ge": 1e-3, "le": 1e6})  # S
    max_walks: int = field(default=10, metadata={"ge": 1, "le": 100})  # K_max
    distance_factor: float = field(default=3.0, metadata={"ge": 1e-3, "le": 1e6})  # omega
    update_ratio: float = field(default=3.0, metadata={"ge": 1e-3, "le": 1e3})  # beta
    directions: int = field(default=20, metadata={"ge": 1, "le": 100})  # h
    iterations: int = field(default=50, metadata={"ge": 1, "le": 10_000})  # T_max
    max_summon_steps: int = field(default=100, metadata={
        "ge": 0, "le": 1000})  # our cap on one summoning

    name = "wolfpack"

    def __post_init__(self) -> None:
        for name in ("n_wolves", "max_walks", "directions", "iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
        if self.n_wolves < 3:
            raise ValueError("n_wolves must be at least 3")
        for name in ("step_factor", "distance_factor", "update_ratio"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")
        if not 0 < self.scout_fraction < 1:
            raise ValueError("scout_fraction must be in (0, 1)")
        if self.max_summon_steps < 0:
            raise ValueError("max_summon_steps must be non-negative")

    # ---- the three behaviours (the improved pack overrides these) ---------------------------
    def wander_candidates(self, X: np.ndarray, lead: np.ndarray, span: np.ndarray,
                          rng: np.random.Generator) -> np.ndarray:
        """Eq. 26: ``h`` moves of each scout ``X (S, D) -> (S, h, D)``."""
        p = np.arange(1, self.directions + 1)
        step_s = span / self.step_factor
        return X[:, None, :] + np.sin(2 * math.pi * p / self.directions)[None, :, None] * step_s

    def summon_step(self, X: np.ndarray, lead: np.ndarray, span: np.ndarray,
                    rng: np.random.Generator) -> np.ndarray:
        """Eq. 27: one running step of the ferocious wolves ``X (M, D)`` at the lead."""
        step_b = 2.0 * span / self.step_factor
        return X + step_b * np.sign(lead - X)

    def siege_step(self, X: np.ndarray, lead: np.ndarray, span: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray:
        """Eq. 29 with ``step_w = 1/2``: ``x + lambda step_w |G - x|``, lambda ~ U[-1, 1]."""
        lam = rng.uniform(-1.0, 1.0, size=X.shape)
        return X + lam * 0.5 * np.abs(lead - X)

    # ---- the loop ---------------------------------------------------------------------------

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, D = self.n_wolves, pb.dim
        span = np.asarray(pb.upper, float) - np.asarray(pb.lower, float)
        d_near = float(np.mean(span)) / self.distance_factor  # eq. 28
        n_scouts = min(N - 2, max(1, round(self.scout_fraction * N)))
        X = pb.uniform(rng, N)
        F = ev.evaluate(X)
        for _ in range(self.iterations):
            order = np.argsort(F, kind="stable")
            X, F = X[order], F[order]
            lead_i = 0
            scouts = np.arange(1, 1 + n_scouts)
            # Wandering.
            for _walk in range(self.max_walks):
                C = pb.clip(self.wander_candidates(X[scouts], X[lead_i], span, rng))
                FC = ev.evaluate(C.reshape(-1, D)).reshape(len(scouts), -1)
                best = np.argmin(FC, axis=1)
                fb = FC[np.arange(len(scouts)), best]
                better = fb < F[scouts]
                X[scouts[better]] = C[better, best[better]]
                F[scouts[better]] = fb[better]
                if F[scouts].min() < F[lead_i]:
                    lead_i = int(scouts[np.argmin(F[scouts])])
                    break
            # Summoning: every wolf but the lead and the scouts runs at the lead.
            running = np.setdiff1d(np.arange(N), np.concatenate([[lead_i], scouts]))
            for _step in range(self.max_summon_steps):
                far = running[np.linalg.norm(X[running] - X[lead_i], axis=1) > d_near]
                far = far[far != lead_i]
                if len(far) == 0:
                    break
                X[far] = pb.clip(self.summon_step(X[far], X[lead_i], span, rng))
                F[far] = ev.evaluate(X[far])
                if F[far].min() < F[lead_i]:
                    lead_i = int(far[np.argmin(F[far])])
            # Siege: greedy acceptance.
            others = np.delete(np.arange(N), lead_i)
            C = pb.clip(self.siege_step(X[others], X[lead_i], span, rng))
            FC = ev.evaluate(C)
            better = FC < F[others]
            X[others[better]], F[others[better]] = C[better], FC[better]
            # Renewal of the worst R wolves (never the lead).
            lo, hi = math.ceil(N / (2 * self.update_ratio)), math.floor(N / self.update_ratio)
            R = int(rng.integers(min(lo, hi), max(lo, hi) + 1)) if hi >= 1 else 0
            R = min(R, N - 1)
            if R:
                worst = np.argsort(F, kind="stable")[-R:]
                X[worst] = pb.uniform(rng, R)
                F[worst] = ev.evaluate(X[worst])
            ev.end_iteration()
        return f"{self.iterations} iterations"
