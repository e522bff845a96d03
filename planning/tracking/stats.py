"""Repeated gain tuning and the statistics of paper 003's Table 3.

For each tuner, ``runs`` independent tunings (seeds ``seed, seed + 1, ...``) of the PI gains;
the tuned gains of every run are then simulated once more (all runs in one batch) to get the
tracking errors. Per tuner (all errors in mm):

* ``max``: the largest tool error over every step of every run (the worst case);
* ``mean``: the mean over runs of eq. 24 (each run's mean error);
* ``std``: the mean over runs of the standard deviation of the error along the path (the
  paper's "error fluctuation");
* a Wilcoxon rank-sum test (``scipy.stats.ranksums``) of the runs' eq. 24 values against the
  untuned PI's (``UNTUNED_PI_GAINS``, deterministic: its ``runs`` values are equal): ``+``
  when the tuner is better at p < 0.05, ``-`` when worse, ``=`` otherwise.

As in Table 3, ``variation`` is PI's max minus the tuner's max and ``percent`` the tuner's
improvement of the mean over PI's, in percent.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import ranksums

from kinematics.model import RobotModel

from .simulator import UNTUNED_PI_GAINS, Controller, PIGains, Task, TrackingConfig, simulate
from .tuning import GainBounds, tune_gains

__all__ = ["TunerStats", "TrackingTable", "tracking_table", "format_table3", "LABELS",
           "SIGNIFICANCE"]

#: Row labels as in Table 3.
LABELS = {"pi": "PI", "pso": "PI-PSO", "ga": "PI-GA", "aco": "PI-ACO", "gwo": "PI-GWO",
          "hgso": "PI-HGSO"}

#: Level of the rank-sum test.
SIGNIFICANCE = 0.05


@dataclass(frozen=True)
class TunerStats:
    """One row: per-run eq. 24 values ``fitness (R,)``, per-run max and std of the error
    ``(R,)`` (mm), the tuned ``gains`` per run, and the rank-sum p-value against PI."""

    name: str
    fitness: np.ndarray
    run_max: np.ndarray
    run_std: np.ndarray
    gains: tuple[PIGains, ...]
    p_value: float | None = None

    @property
    def max(self) -> float:
        return float(self.run_max.max())

    @property
    def mean(self) -> float:
        return float(self.fitness.mean())

    @property
    def std(self) -> float:
        return float(self.run_std.mean())

    @property
    def best_run(self) -> int:
        return int(np.argmin(self.fitness))

    def sign(self, baseline: TunerStats) -> str:
        if self.p_value is None or not self.p_value < SIGNIFICANCE:
            return "="
        return "+" if np.median(self.fitness) < np.median(baseline.fitness) else "-"


@dataclass(frozen=True)
class TrackingTable:
    """Table 3 for one task: ``baseline`` (untuned PI) and one row per tuner."""

    task: str
    baseline: TunerStats
    rows: tuple[TunerStats, ...]


def _stats(model: RobotModel, task: Task, name: str, gains: Sequence[PIGains],
           controller: Controller, config: TrackingConfig) -> TunerStats:
    res = simulate(model, task, list(gains), controller=controller, config=config,
                   record=False)
    return TunerStats(name, res.mean_error, res.max_error, res.std_error, tuple(gains))


def tracking_table(
    model: RobotModel,
    task: Task,
    tuners: Sequence[str] = ("pso", "ga", "aco", "gwo", "hgso"),
    *,
    runs: int = 30,
    seed: int = 0,
    controller: Controller = "pi",
    config: TrackingConfig | None = None,
    bounds: GainBounds | None = None,
    iterations: int | None = None,
    baseline: PIGains = UNTUNED_PI_GAINS,
    progress: Callable[[float], None] | None = None,
) -> TrackingTable:
    """Tune ``runs`` times per tuner (seeds ``seed .. seed + runs - 1``) and tabulate.

    ``config`` and ``bounds`` default to ``TrackingConfig()`` and ``GainBounds()``;
    ``iterations`` overrides Table 2's 50 (shorter runs for tests); ``progress`` gets the
    fraction of all tunings done.
    """
    config = TrackingConfig() if config is None else config
    bounds = GainBounds() if bounds is None else bounds
    if runs < 1:
        raise ValueError(f"runs: must be at least 1, got {runs}")
    base = _stats(model, task, "pi", [baseline] * runs, controller, config)
    rows = []
    total = runs * len(tuners)
    for i, name in enumerate(tuners):
        gains = []
        for r in range(runs):
            def sub(f: float, done: int = i * runs + r) -> None:
                if progress is not None:
                    progress((done + f) / total)

            gains.append(tune_gains(model, task, name, seed + r, controller=controller,
                                    config=config, bounds=bounds, iterations=iterations,
                                    progress=sub).gains)
        row = _stats(model, task, name, gains, controller, config)
        p = float(ranksums(row.fitness, base.fitness).pvalue)
        rows.append(TunerStats(row.name, row.fitness, row.run_max, row.run_std, row.gains, p))
    return TrackingTable(task.kind, base, tuple(rows))


def format_table3(table: TrackingTable, paper: dict | None = None) -> str:
    """Table 3's layout in mm (max, variation, mean, percent, std, rank-sum sign and p);
    ``paper`` (``{label: {"max": m, "mean": m, "std": m}}`` in metres) adds its values."""
    b = table.baseline
    head = (f"{table.task:<8}{'algorithm':<10}{'max':>9}{'variation':>11}{'mean':>10}"
            f"{'percent':>9}{'std':>10}{'ranksum':>9}{'p':>10}")
    if paper:
        head += f"   | paper: {'max':>7}{'mean':>9}{'std':>9}"
    lines = [head]
    for row in (b, *table.rows):
        label = LABELS.get(row.name, row.name)
        if row is b:
            cells = (f"{row.max:9.4f}{'/':>11}{row.mean:10.4f}{'/':>9}{row.std:10.4f}"
                     f"{'/':>9}{'':>10}")
        else:
            pct = 100.0 * (b.mean - row.mean) / b.mean
            cells = (f"{row.max:9.4f}{b.max - row.max:11.4f}{row.mean:10.4f}{pct:8.2f}%"
                     f"{row.std:10.4f}{row.sign(b):>9}{row.p_value:10.2g}")
        line = f"{'':<8}{label:<10}{cells}"
        if paper:
            ref = paper.get(label, {})

            mm = [f"{1e3 * ref[k]:.4g}" if k in ref else "-" for k in ("max", "mean", "std")]
            line += f"   |        {mm[0]:>7}{mm[1]:>9}{mm[2]:>9}"
        lines.append(line)
    return "\n".join(lines)
