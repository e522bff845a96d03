"""Obstacle-avoiding tool paths: encoding, penalised cost, exact verification, shortcutting.

A metaheuristic sees a path as ``k`` intermediate waypoints between a fixed start and goal,
flattened to a vector of ``3k`` coordinates inside the scene's bounds. Its cost is

    length + penalty * (sum over segments and obstacles of max(0, margin' - clearance))

(an exact L1 penalty: with a large enough weight the minimiser is feasible), where
``margin' = safety_margin + slack`` is slightly larger than the scene's margin so that a
path the optimiser thinks is free survives the exact check. The penalty only guides the
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

from .optimisers.base import Problem, ProgressFn
from .registry import algorithm_names, make
from .scene import Scene
from .status import PlanStatus

__all__ = [
    "ALGORITHMS",
    "PathEncoding",
    "PathResult",
    "path_length",
    "shortcut",
    "plan_path",
    "make_optimiser",
]

#: Every planner ``plan_path`` knows: the ``path`` family of ``planning.registry``.
ALGORITHMS = algorithm_names("path")

#: Intermediate waypoints of the encoding per algorithm. The GA's is paper 000's chromosome
#: length (5); the paper gives none for the wolves and the fish, which get the same 5.
DEFAULT_WAYPOINTS = {"wolfpack": 5, "wolfpack_improved": 5, "ga": 5, "afsa": 5}

#: Weight of the penetration (mm of length per mm of depth) in the penalised cost.
DEFAULT_PENALTY = 1000.0
#: Planning slack added to the safety margin, as a fraction of the scene's diagonal.
SLACK_FRACTION = 1e-4
#: Random shortcuts tried after the greedy pass.
DEFAULT_RANDOM_SHORTCUTS = 100


def path_length(path) -> float:
    """Length (mm) of a polyline ``(n, 3)``."""
    path = np.asarray(path, dtype=float)
    return float(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))


@dataclass(frozen=True)
class PathEncoding:
    """``k`` waypoints between ``start`` and ``goal`` as a flat vector ``(3k,)`` in bounds.

    ``cost(X: (P, 3k)) -> (P,)`` is the penalised length; ``problem()`` the box problem
    the optimisers minimise.
    """

    scene: Scene
    start: np.ndarray
    goal: np.ndarray
    k: int
    penalty: float = DEFAULT_PENALTY
    margin: float | None = None

    @property
    def planning_margin(self) -> float:
        """The margin the cost penalises against: safety margin plus a small slack."""
        if self.margin is not None:
            return self.margin
        return self.scene.safety_margin + SLACK_FRACTION * self.scene.diagonal

    def decode(self, X) -> np.ndarray:
        """Full polylines ``(P, k+2, 3)`` from flat waypoints ``(P, 3k)``."""
        X = np.asarray(X, dtype=float).reshape(-1, self.k, 3)
        P = len(X)
        return np.concatenate([np.broadcast_to(self.start, (P, 1, 3)), X,
                               np.broadcast_to(self.goal, (P, 1, 3))], axis=1)

    def cost(self, X) -> np.ndarray:
        """Penalised length ``(P,)`` of flat waypoints ``X (P, 3k)``."""
        paths = self.decode(X)
        return self.paths_cost(paths)

    def paths_cost(self, paths: np.ndarray) -> np.ndarray:
        """Penalised length ``(P,)`` of polylines ``(P, n, 3)``."""
        seg = np.diff(paths, axis=1)
        length = np.sqrt(np.sum(seg * seg, axis=2)).sum(axis=1)
        if not self.scene.obstacles:
            return length
        P, n = paths.shape[:2]
        c = self.scene.segment_clearance(paths[:, :-1].reshape(-1, 3),
                                         paths[:, 1:].reshape(-1, 3))
        pen = np.maximum(self.planning_margin - c, 0.0).reshape(P, -1).sum(axis=1)
        return length + self.penalty * pen

    def problem(self) -> Problem:
        lower = np.tile(self.scene.lower, self.k)
        upper = np.tile(self.scene.upper, self.k)
        return Problem(self.cost, lower, upper)


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


def _dedupe(path: np.ndarray) -> np.ndarray:
    """Drop consecutive duplicate vertices (keeps at least start and goal)."""
    keep = np.ones(len(path), dtype=bool)
    keep[1:] = np.any(np.abs(np.diff(path, axis=0)) > 0, axis=1)
    keep[-1] = True
    out = path[keep]
    return out if len(out) >= 2 else np.vstack([path[0], path[-1]])


def shortcut(scene: Scene, path, rng: np.random.Generator | None = None,
             random_tries: int = DEFAULT_RANDOM_SHORTCUTS, margin: float | None = None
             ) -> np.ndarray:
    """Shorten a clear polyline ``(n, 3)``, keeping it clear (exact check at ``margin``,
    default the scene's safety margin).

    Greedy pass: from each kept vertex jump to the farthest later vertex it sees. Then
    ``random_tries`` seeded random shortcuts between two points anywhere on the path
    (vertices or inside segments), each kept only if the connecting segment is clear.
    """
    margin = scene.safety_margin if margin is None else margin
    path = _dedupe(np.asarray(path, dtype=float))

    def clear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        if not scene.obstacles:
            return np.ones(len(a), dtype=bool)
        return scene.min_segment_clearance(a, b) >= margin

    out, i = [path[0]], 0
    while i < len(path) - 1:
        later = path[i + 1:]
        ok = clear(np.broadcast_to(path[i], later.shape), later)
        j = i + 1 + (int(np.nonzero(ok)[0].max()) if ok.any() else 0)
        out.append(path[j])
        i = j
    path = np.array(out)
    if rng is None or random_tries <= 0:
        return path
    for _ in range(random_tries):
        n = len(path)
        if n <= 2:
            break
        seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        s1, s2 = np.sort(rng.uniform(0.0, cum[-1], size=2))
        i1 = min(int(np.searchsorted(cum, s1, side="right")) - 1, n - 2)
        i2 = min(int(np.searchsorted(cum, s2, side="right")) - 1, n - 2)
        if i1 == i2:
            continue
        p1 = path[i1] + (s1 - cum[i1]) / max(seg[i1], 1e-300) * (path[i1 + 1] - path[i1])
        p2 = path[i2] + (s2 - cum[i2]) / max(seg[i2], 1e-300) * (path[i2 + 1] - path[i2])
        if clear(p1[None], p2[None])[0]:
            path = _dedupe(np.vstack([path[: i1 + 1], p1, p2, path[i2 + 1:]]))
    return path


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
    if algorithm not in ALGORITHMS:
        raise FieldError("algorithm", f"algorithm must be one of {', '.join(ALGORITHMS)}, "
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
        from . import auto_planner

        fn = auto_planner.plan_auto if algorithm == "auto" else auto_planner.plan_rrt_star
        raw = fn(scene, start, goal, rng, params=params, progress=progress)
        history, evaluations, extra = raw.history, raw.evaluations, raw.extra
        candidate, none_found = raw.path, raw.status
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
        if algorithm == "aca":
            res = opt.plan_layers(scene, start, goal, rng, penalty=penalty,
                                  max_evaluations=max_evals, progress=progress)
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
    path = shortcut(scene, candidate, rng, tries) if do_shortcut else _dedupe(candidate)
    return PathResult(
        path=path, length=path_length(path), min_clearance=scene.path_clearance(path),
        runtime_s=time.perf_counter() - t0, convergence=np.asarray(history, dtype=float),
        algorithm=algorithm, evaluations=int(evaluations), status=PlanStatus.OK,
        message="clear path found" + (", shortened by shortcutting" if do_shortcut else ""),
        raw_length=raw_length, extra=extra,
    )
