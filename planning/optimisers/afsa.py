"""Artificial fish swarm algorithm (AFSA, Li 2002): paper 000's "basic AFSA" baseline.

Each iteration every fish tries two behaviours and keeps the better outcome:

* **swarm**: move towards the centre of the fish within ``visual`` if the centre is better
  and not crowded;
* **follow**: move towards the best fish within ``visual`` if it is better and not crowded;

either falls back to **prey**: up to ``try_number`` random points within ``visual``; move
towards the first that is better, else take a random step. A move towards ``y`` is
``x + rand * step * (y - x) / ||y - x||``. The bulletin board is the evaluator's best.

Paper 000 (section 4.3): 50 fish, visual 50, step 3, crowding factor 10, 50 tries, 100
iterations, on its 100 mm scene. ``visual`` and ``step`` here are fractions of the mean box
range (0.5 and 0.03, the paper's 50 and 3 on its 100 mm scene), so the same defaults suit any
scene. Crowding: with a factor ``delta`` > 1 (the paper's 10) we read "not crowded" as fewer
than ``N / delta`` fish in view (5 of 50); the textbook test ``n_f / N < delta`` with
``delta < 1`` is the same rule with ``delta`` inverted. The paper's "dimension of solution 3"
is one waypoint; our path encoding has 3 coordinates per waypoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .base import Budget, Optimiser

__all__ = ["FishSwarm"]


@dataclass(frozen=True)
class FishSwarm(Optimiser):
    """Artificial fish swarm; defaults = paper 000."""

    n_fish: int = field(default=50, metadata={"ge": 2, "le": 300})
    visual: float = field(default=0.5, metadata={  # paper: 50 on a 100 mm scene
        "gt": 0.0, "le": 10.0, "description": "fraction of the mean range"})
    step: float = field(default=0.03, metadata={  # paper: 3
        "gt": 0.0, "le": 10.0, "description": "fraction of the mean range"})
    crowding: float = field(default=10.0, metadata={"ge": 1e-3, "le": 1e6})
    try_number: int = field(default=50, metadata={"ge": 1, "le": 300})
    iterations: int = field(default=100, metadata={"ge": 1, "le": 10_000})

    name = "afsa"

    def __post_init__(self) -> None:
        if self.n_fish < 2:
            raise ValueError("n_fish must be at least 2")
        for name in ("try_number", "iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1")
        for name in ("visual", "step", "crowding"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")

    def _run(self, ev: Budget, rng: np.random.Generator) -> str:
        pb = ev.problem
        N, D = self.n_fish, pb.dim
        scale = float(np.mean(np.asarray(pb.upper, float) - np.asarray(pb.lower, float)))
        visual, step = self.visual * scale, self.step * scale
        X = pb.uniform(rng, N)
        F = ev.evaluate(X)
        rows = np.arange(N)

        def toward(x: np.ndarray, y: np.ndarray) -> np.ndarray:
            d = y - x
            n = np.linalg.norm(d, axis=1, keepdims=True)
            return pb.clip(x + rng.random((len(x), 1)) * step * d / np.where(n > 0, n, 1.0))

        for _ in range(self.iterations):
            dist = np.linalg.norm(X[:, None, :] - X[None, :, :], axis=2)
            seen = (dist < visual) & ~np.eye(N, dtype=bool)
            n_f = seen.sum(axis=1)
            roomy = (n_f > 0) & (n_f < N / self.crowding)
            # Prey, for every fish (both behaviours may fall back to it).
            T = X[:, None, :] + visual * rng.uniform(-1.0, 1.0, size=(N, self.try_number, D))
            T = pb.clip(T)
            FT = ev.evaluate(T.reshape(-1, D)).reshape(N, -1)
            found = FT < F[:, None]
            first = np.argmax(found, axis=1)
            prey_target = T[rows, first]
            prey = np.where(found.any(axis=1)[:, None], toward(X, prey_target),
                            pb.clip(X + step * rng.uniform(-1.0, 1.0, size=(N, D))))
            # Swarm: the centre of the fish in view.
            centre = (seen.astype(float) @ X) / np.maximum(n_f, 1)[:, None]
            Fc = ev.evaluate(centre)
            swarm = np.where(((Fc < F) & roomy)[:, None], toward(X, centre), prey)
            # Follow: the best fish in view.
            Fseen = np.where(seen, F[None, :], np.inf)
            buddy = np.argmin(Fseen, axis=1)
            follow = np.where(((Fseen[rows, buddy] < F) & roomy)[:, None],
                              toward(X, X[buddy]), prey)
            Fs, Ff = ev.evaluate(swarm), ev.evaluate(follow)
            use_s = Fs <= Ff
            X = np.where(use_s[:, None], swarm, follow)
            F = np.where(use_s, Fs, Ff)
            ev.end_iteration()
        return f"{self.iterations} iterations"
