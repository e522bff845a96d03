"""PI gain tuning for the tracking controller (paper 003, Table 2): a metaheuristic
minimises eq. 24, the mean tool error of ``simulator.simulate``, over the gains
``(kp_xy, kp_z, ki)`` inside ``GainBounds``.

The tuners are the ``tuner`` family of ``planning.registry`` (HGSO, PSO, GA, ACO_R, GWO),
each with Table 2's parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinematics.model import RobotModel

from ..optimisers.acor import ACOR
from ..optimisers.base import OptimResult, Problem, ProgressFn
from ..optimisers.ga import GeneticAlgorithm
from ..optimisers.hgso import HGSO
from ..optimisers.pso import PSO
from ..registry import algorithm_classes, make
from .simulator import Controller, PIGains, Task, TrackingConfig, tracking_fitness

__all__ = [
    "GainBounds",
    "TUNERS",
    "make_tuner",
    "tuner_budget",
    "TuningResult",
    "tune_gains",
]


@dataclass(frozen=True)
class GainBounds:
    """Search box of the tuners: ``kp`` (1/s) and ``ki`` (1/s^2) as ``(low, high)``.

    The defaults enclose the whole discrete stability region at dt = 0.1 s (kp < 2/dt,
    ki < 4/dt^2), so a tuner has to find its edge rather than be stopped by the box; the
    lower kp bound keeps the tuned loop damped (see ``planning.tracking.simulator``).
    """

    kp: tuple[float, float] = (0.5, 20.0)
    ki: tuple[float, float] = (0.0, 400.0)

    def __post_init__(self) -> None:
        for name in ("kp", "ki"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi)):
                raise ValueError(f"{name}: bounds must be finite")
            if lo < 0:
                raise ValueError(f"{name}: the lower bound must be >= 0, got {lo}")
            if hi <= lo:
                raise ValueError(f"{name}: the upper bound must exceed the lower, got {(lo, hi)}")
            object.__setattr__(self, name, (lo, hi))

    @property
    def lower(self) -> np.ndarray:
        return np.array([self.kp[0], self.kp[0], self.ki[0]])

    @property
    def upper(self) -> np.ndarray:
        return np.array([self.kp[1], self.kp[1], self.ki[1]])



# ---- the tuners ------------------------------------------------------------------------
#: The gain tuners of paper 003 (Table 2 parameters: population 50, 50 iterations each),
#: name -> optimiser dataclass: the ``tuner`` family of ``planning.registry`` (``aco`` is
#: ACO_R, the continuous ant colony).
TUNERS: dict[str, type] = algorithm_classes("tuner")


def make_tuner(name: str, iterations: int | None = None):
    """The tuner ``name`` with Table 2's parameters (``iterations`` overrides Nc):
    ``registry.make("tuner", name, ...)``; ``FieldError`` naming ``tune`` for an unknown
    name."""
    return make("tuner", name, None if iterations is None else {"iterations": iterations})


def tuner_budget(opt) -> int:
    """Evaluations a tuner spends on its full run (initial population + iterations)."""
    if isinstance(opt, GeneticAlgorithm):
        return opt.population + opt.iterations * (opt.population - opt.elite)
    if isinstance(opt, ACOR):
        return opt.archive_size + opt.iterations * opt.n_ants
    pop = opt.n_gases if isinstance(opt, HGSO) else \
        opt.n_particles if isinstance(opt, PSO) else opt.n_wolves
    return pop * (opt.iterations + 1)


@dataclass(frozen=True)
class TuningResult:
    """Tuned ``gains``, their fitness (eq. 24, mm) and the optimiser's run."""

    gains: PIGains
    fitness: float
    optim: OptimResult


def tune_gains(
    model: RobotModel,
    task: Task,
    tuner: str = "hgso",
    rng: np.random.Generator | int = 0,
    *,
    controller: Controller = "pi",
    config: TrackingConfig = TrackingConfig(),  # noqa: B008 - frozen, never mutated
    bounds: GainBounds = GainBounds(),
    iterations: int | None = None,
    max_evaluations: int | None = None,
    progress: ProgressFn | None = None,
) -> TuningResult:
    """Tune ``(kp_xy, kp_z, ki)`` within ``bounds`` to minimise eq. 24 with ``tuner``
    ("hgso", "pso", "ga", "aco" or "gwo"); reproducible for a given seed or Generator.
    ``max_evaluations`` defaults to the tuner's full run (``tuner_budget``)."""
    opt = make_tuner(tuner, iterations)
    if max_evaluations is None:
        max_evaluations = tuner_budget(opt)
    rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    problem = Problem(tracking_fitness(model, task, controller=controller, config=config),
                      bounds.lower, bounds.upper)
    res = opt.minimize(problem, rng, max_evaluations=max_evaluations, progress=progress)
    return TuningResult(PIGains.from_vector(res.x), res.fun, res)
