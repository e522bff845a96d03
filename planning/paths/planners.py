"""``plan_path``: obstacle-avoiding tool paths from any planner, verified and shortened.

The metaheuristics (``planning.optimisers``) minimise the penalised length of a path encoded
as a flat vector (``planning.paths.encoding``); the ant colony searches the scene's slices
itself; ``auto`` and ``rrt_star`` are ``planning.paths.auto``'s; a registered
``planning.search.SamplingPlanner`` searches the scene's box through the sampling core
(``planning.search``). The penalty only guides the
search: ``plan_path`` never trusts it. It verifies the best path with the scene's exact
segment check, returns an honest failure (no path, ``status`` ``collision``, a message naming
the obstacle) when the path still collides, and otherwise shortens it by shortcutting (greedy,
then seeded random shortcuts), each shortcut kept only if the exact check passes.

Lengths in mm, times in s. Paths are ``(n, 3)`` polylines from start to goal.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.numbers import finite_or_none

from ..optimisers.aca import AntColony
from ..optimisers.base import Problem, ProgressFn
from ..registry import algorithm_names, lookup, make
from ..search import STEP_FRACTION, BoxSpace, SamplingPlanner
from ..status import PlanStatus
from .auto import plan_auto, plan_rrt_star
from .encoding import (
    DEFAULT_PENALTY,
    DEFAULT_RANDOM_SHORTCUTS,
    PathEncoding,
    dedupe,
    path_length,
    planning_slack,
    shortcut,
)
from .scene import Scene

__all__ = [
    "ALGORITHMS",
    "PathResult",
    "plan_path",
    "make_optimiser",
]

#: Every planner ``plan_path`` knows: the ``path`` family of ``planning.registry``.
ALGORITHMS = algorithm_names("path")

#: Intermediate waypoints of the encoding per algorithm. The GA's is paper 000's chromosome
#: length (5); the paper gives none for the wolves and the fish, which get the same 5.
DEFAULT_WAYPOINTS = {"wolfpack": 5, "wolfpack_improved": 5, "ga": 5, "afsa": 5}


@dataclass(frozen=True)
class PathResult:
    """A planned path. ``path (n, 3)`` mm from start to goal, empty unless ``status`` is
    ``ok`` (a path that collides is never returned); ``length`` mm (inf on failure);
    ``min_clearance`` mm (of the returned path, or of the rejected candidate on failure;
    inf with no obstacles); ``convergence`` = best cost after each iteration. ``status``:
    ``ok``, ``collision`` (the best path found hits an obstacle), ``no_path`` (the search
    found none) or ``budget_spent`` (its samples ran out first)."""

    path: np.ndarray
    length: float
    min_clearance: float
    runtime_s: float
    convergence: np.ndarray
    algorithm: str
    evaluations: int
    status: PlanStatus
    message: str
    raw_length: float = math.inf
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (inf and NaN become None)."""
        return {
            "path": self.path.tolist(),
            "length": finite_or_none(self.length),
            "min_clearance": finite_or_none(self.min_clearance),
            "runtime_s": self.runtime_s,
            "convergence": [finite_or_none(v)
                            for v in np.asarray(self.convergence, dtype=float)],
            "algorithm": self.algorithm,
            "evaluations": self.evaluations,
            "success": self.success,
            "status": self.status.value,
            "message": self.message,
            "raw_length": finite_or_none(self.raw_length),
        }


def make_optimiser(algorithm: str, params: dict[str, Any] | None = None):
    """The optimiser dataclass of a metaheuristic with ``params`` overriding its defaults
    (the paper's): ``registry.make("path", algorithm, params)``. ``FieldError`` naming
    ``algorithm``, an unknown ``params.<name>``, or ``params`` when the values do not go
    together."""
    return make("path", algorithm, params)


def _heartbeat(problem: Problem, progress: ProgressFn, every_s: float = 0.2) -> Problem:
    """``problem`` whose objective also calls ``progress(0.0)`` every ``every_s`` seconds:
    without an evaluation budget there is no fraction to report, but a job can still be
    cancelled (``progress`` raises) while the optimiser runs."""
    last = [time.perf_counter()]

    def f(X: np.ndarray) -> np.ndarray:
        now = time.perf_counter()
        if now - last[0] >= every_s:
            last[0] = now
            progress(0.0)
        return problem.f(X)

    return Problem(f, problem.lower, problem.upper)


def _failure(algorithm: str, t0: float, status: PlanStatus, message: str, **kw) -> PathResult:
    return PathResult(path=np.empty((0, 3)), length=math.inf,
                      min_clearance=kw.pop("min_clearance", math.nan),
                      runtime_s=time.perf_counter() - t0,
                      convergence=kw.pop("convergence", np.empty(0)), algorithm=algorithm,
                      evaluations=kw.pop("evaluations", 0), status=status, message=message,
                      **kw)


def _blocking(scene: Scene, path: np.ndarray) -> str:
    """Which obstacle a colliding path hits, and how deep, for a failure message."""
    c = scene.segment_clearance(path[:-1], path[1:])
    seg, k = np.unravel_index(int(np.argmin(c)), c.shape)
    return (f"segment {seg} comes {c[seg, k]:.3f} mm from obstacles[{k}] "
            f"(needs at least safety_margin = {scene.safety_margin} mm)")


def plan_path(
    scene: Scene,
    start,
    goal,
    algorithm: str = "auto",
    seed: int | np.random.Generator = 0,
    params: dict[str, Any] | None = None,
    progress: ProgressFn | None = None,
) -> PathResult:
    """Plan a clear path from ``start`` to ``goal`` (mm) in ``scene``.

    ``algorithm``: one of ``ALGORITHMS``. ``params``: the optimiser's parameters (see its
    dataclass; defaults are paper 000's) and the common ``waypoints`` (k), ``penalty``,
    ``max_evaluations``, ``shortcut`` (default True) and ``random_shortcuts``; for
    ``rrt_star``/``auto`` the planner's own options. ``progress(fraction)`` may raise to
    stop. Invalid input raises ``FieldError`` naming the field (``start``, ``goal``,
    ``params.<name>``); a planner that finds no clear path returns a failed ``status`` with
    a message.
    """
    t0 = time.perf_counter()
    known = algorithm_names("path")  # planners registered after this module loaded too
    if algorithm not in known:
        raise FieldError("algorithm", f"algorithm must be one of {', '.join(known)}, "
                         f"got {algorithm!r}")
    start = scene.check_endpoint(start, "start")
    goal = scene.check_endpoint(goal, "goal")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    params = dict(params or {})
    do_shortcut = bool(params.pop("shortcut", True))
    tries = int(params.pop("random_shortcuts", DEFAULT_RANDOM_SHORTCUTS))
    if tries < 0:
        raise FieldError(("params", "random_shortcuts"),
                         "params.random_shortcuts must be non-negative")

    if algorithm in ("auto", "rrt_star"):
        fn = plan_auto if algorithm == "auto" else plan_rrt_star
        raw = fn(scene, start, goal, rng, params=params, progress=progress)
        history, evaluations, extra = raw.history, raw.evaluations, raw.extra
        candidate, none_found = raw.path, raw.status
    elif issubclass(lookup("path", algorithm).params, SamplingPlanner):
        planner = make("path", algorithm, params)
        margin = scene.safety_margin + planning_slack(scene)
        space = BoxSpace(scene.lower, scene.upper, STEP_FRACTION * scene.diagonal,
                         lambda a, b: scene.segments_clear(a, b, margin))
        found = planner.search(space, start, goal, rng, progress=progress)
        history, evaluations = found.history, int(found.stats.get("nodes", 0))
        extra = {**found.stats, "message": f"{algorithm}: no path to the goal "
                 f"({found.status.value})"} if found.path is None else dict(found.stats)
        candidate, none_found = found.path, found.status
    else:
        k = int(params.pop("waypoints", DEFAULT_WAYPOINTS.get(algorithm, 5)))
        if k < 1:
            raise FieldError(("params", "waypoints"), "params.waypoints must be at least 1")
        penalty = float(params.pop("penalty", DEFAULT_PENALTY))
        if not penalty > 0:
            raise FieldError(("params", "penalty"), "params.penalty must be positive")
        max_evals = params.pop("max_evaluations", None)
        if max_evals is not None and int(max_evals) < 1:
            raise FieldError(("params", "max_evaluations"),
                             "params.max_evaluations must be at least 1")
        opt = make_optimiser(algorithm, params)
        if isinstance(opt, AntColony):  # searches the scene's slices, not a flat encoding
            enc = PathEncoding(scene, start, goal, opt.n_slices, penalty)
            res = opt.plan_layers(enc, rng, max_evaluations=max_evals, progress=progress)
            candidate = res.extra["path"]
        else:
            enc = PathEncoding(scene, start, goal, k, penalty)
            problem = enc.problem()
            if progress is not None and max_evals is None:
                problem = _heartbeat(problem, progress)
            res = opt.minimize(problem, rng, max_evaluations=max_evals, progress=progress)
            candidate = enc.decode(res.x)[0]
        history, evaluations = res.history, res.evaluations
        extra = {"optimiser": res.message, "message": res.extra.get("message", "no path found")}
        none_found = PlanStatus.NO_PATH  # no ant of the ACA reached the goal
    if candidate is None:
        return _failure(algorithm, t0, none_found, extra.get("message", "no path found"),
                        convergence=history, evaluations=evaluations)
    candidate = np.asarray(candidate, dtype=float)
    raw_length = path_length(candidate)
    clearance = scene.path_clearance(candidate)
    if not scene.path_is_clear(candidate):
        return _failure(algorithm, t0, PlanStatus.COLLISION,
                        f"{algorithm} found no clear path: its best path's "
                        f"{_blocking(scene, candidate)}", min_clearance=clearance,
                        convergence=history, evaluations=evaluations, raw_length=raw_length)
    path = shortcut(scene, candidate, rng, tries) if do_shortcut else dedupe(candidate)
    return PathResult(
        path=path, length=path_length(path), min_clearance=scene.path_clearance(path),
        runtime_s=time.perf_counter() - t0, convergence=np.asarray(history, dtype=float),
        algorithm=algorithm, evaluations=int(evaluations), status=PlanStatus.OK,
        message="clear path found" + (", shortened by shortcutting" if do_shortcut else ""),
        raw_length=raw_length, extra=extra,
    )
