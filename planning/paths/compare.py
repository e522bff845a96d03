"""Run planners over many seeds on one scene: rows shaped like paper 000's Tables 3 and 4.

Paper 000 reports, per algorithm, the best path length, the average path length and the
running time. ``compare_planners`` runs each algorithm once per seed (seeds ``0..runs-1``
offset by ``seed``) and reports those three over the successful runs, plus the number of
successes, the mean length of the optimisers' own paths before shortcutting (what the
paper's figures show) and the mean number of objective evaluations.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.numbers import finite_or_none

from .planners import ALGORITHMS, plan_path
from .scene import Scene

__all__ = ["CompareRow", "RunOutcome", "compare_planners", "compare_runs", "compare_row",
           "check_compare", "toy_scene", "TOY_START", "TOY_GOAL"]


#: Start and goal (mm) of the toy scenes: opposite corners of a 100 mm cube.
TOY_START, TOY_GOAL = (1.0, 1.0, 1.0), (100.0, 100.0, 100.0)


def toy_scene(layout: int = 0, margin: float = 0.0) -> Scene:
    """A toy scene like paper 000's §4.4 (which prints no obstacle positions): five spheres
    of radius 12-18 mm across the diagonal from ``TOY_START`` to ``TOY_GOAL`` of a 100 mm
    cube, jittered by up to 10 mm; ``layout`` seeds the jitter and the radii."""
    rng = np.random.default_rng(layout)
    s, g = np.array(TOY_START), np.array(TOY_GOAL)
    t = np.array([0.2, 0.35, 0.5, 0.65, 0.8])
    centres = s + t[:, None] * (g - s) + rng.uniform(-10, 10, (5, 3))
    radii = rng.uniform(12, 18, 5)
    return Scene.create([[0, 0, 0], [100, 100, 100]],
                        [{"center": c.tolist(), "radius": float(r)}
                         for c, r in zip(centres, radii)], margin)


@dataclass(frozen=True)
class CompareRow:
    """One algorithm over ``runs`` seeds. Lengths in mm (NaN when no run succeeded),
    times in s."""

    algorithm: str
    runs: int
    successes: int
    best_length: float
    mean_length: float
    mean_raw_length: float
    mean_time_s: float
    mean_evaluations: float

    def to_dict(self) -> dict[str, Any]:
        return {k: finite_or_none(v) if isinstance(v, float) else v
                for k, v in asdict(self).items()}


@dataclass(frozen=True)
class RunOutcome:
    """What a row needs of one planner run: success, lengths (mm), time (s), evaluations."""

    success: bool
    length: float
    raw_length: float
    runtime_s: float
    evaluations: int


def check_compare(algorithms: Sequence[str], runs: int,
                  params: dict[str, dict[str, Any]] | None) -> None:
    """``FieldError`` naming ``runs``, ``algorithms`` or ``params.<algorithm>``."""
    if runs < 1:
        raise FieldError("runs", "runs must be at least 1")
    for k, a in enumerate(algorithms):
        if a not in ALGORITHMS:
            raise FieldError(("algorithms", k), f"algorithms: unknown algorithm {a!r}; known: "
                             f"{', '.join(ALGORITHMS)}")
    unknown = sorted(set(params or {}) - set(algorithms))
    if unknown:
        raise FieldError(("params", unknown[0]),
                         f"params.{unknown[0]} names no algorithm being compared")


def compare_runs(scene: Scene, start, goal, algorithm: str, seeds: Sequence[int],
                 params: dict[str, Any] | None = None,
                 progress: Callable[[float], None] | None = None) -> list[RunOutcome]:
    """``algorithm`` planned once per seed of ``seeds``, in order (``params`` as for
    ``plan_path``). A run depends on its seed alone, so runs may be split among processes;
    ``progress(fraction)`` after each."""
    out = []
    for i, s in enumerate(seeds):
        x = plan_path(scene, start, goal, algorithm, s, params)
        out.append(RunOutcome(bool(x.success), float(x.length), float(x.raw_length),
                              float(x.runtime_s), int(x.evaluations)))
        if progress is not None:
            progress((i + 1) / len(seeds))
    return out


def compare_row(algorithm: str, outcomes: Sequence[RunOutcome]) -> CompareRow:
    """The row of ``algorithm`` over its runs' outcomes (in seed order): best and mean
    length and mean raw length over the successful runs (NaN without one), mean time and
    mean evaluations over all."""
    ok = [x for x in outcomes if x.success]
    lengths = np.array([x.length for x in ok])
    raw = np.array([x.raw_length for x in ok])
    return CompareRow(
        algorithm=algorithm, runs=len(outcomes), successes=len(ok),
        best_length=float(lengths.min()) if len(ok) else math.nan,
        mean_length=float(lengths.mean()) if len(ok) else math.nan,
        mean_raw_length=float(raw.mean()) if len(ok) else math.nan,
        mean_time_s=float(np.mean([x.runtime_s for x in outcomes])),
        mean_evaluations=float(np.mean([x.evaluations for x in outcomes])),
    )


def compare_planners(
    scene: Scene,
    start,
    goal,
    algorithms: Sequence[str] = ALGORITHMS,
    runs: int = 30,
    seed: int = 0,
    params: dict[str, dict[str, Any]] | None = None,
    progress: Callable[[float], None] | None = None,
) -> list[CompareRow]:
    """Plan with every algorithm for ``runs`` seeds; one row per algorithm, in order
    (``compare_runs`` then ``compare_row`` for each).

    ``params`` maps an algorithm to its parameters (as for ``plan_path``). ``FieldError``
    naming ``runs``, ``algorithms`` or ``params.<algorithm>``.
    """
    check_compare(algorithms, runs, params)
    params = params or {}
    rows = []
    seeds = [seed + r for r in range(runs)]
    for k, a in enumerate(algorithms):
        def sub(f: float, k: int = k) -> None:
            if progress is not None:
                progress((k + f) / len(algorithms))

        rows.append(compare_row(a, compare_runs(scene, start, goal, a, seeds, params.get(a),
                                                sub)))
    return rows
