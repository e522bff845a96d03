"""What the path planners and the optimisers that search the scene share: the encoding of
a path as a flat vector, its penalised cost, the planning slack and shortcutting.

A metaheuristic sees a path as ``k`` intermediate waypoints between a fixed start and goal,
flattened to a vector of ``3k`` coordinates inside the scene's bounds. Its cost is

    length + penalty * (sum over segments and obstacles of max(0, margin' - clearance))

(an exact L1 penalty: with a large enough weight the minimiser is feasible), where
``margin' = safety_margin + slack`` is slightly larger than the scene's margin so that a
path the optimiser thinks is free survives the exact check. ``shortcut`` shortens a clear
path, keeping every shortcut only if the exact check passes.

This module imports no planner and no optimiser but the ``Problem`` it hands them, so both
``planning.paths.planners`` and ``planning.optimisers.aca`` build on it.

Lengths in mm. Paths are ``(n, 3)`` polylines from start to goal.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..optimisers.base import Problem
from ..search.shortcut import dedupe, farthest_visible, shortcut_chords
from .scene import Scene

__all__ = [
    "DEFAULT_PENALTY",
    "DEFAULT_RANDOM_SHORTCUTS",
    "SLACK_FRACTION",
    "PathEncoding",
    "dedupe",
    "path_length",
    "planning_slack",
    "shortcut",
]

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


def planning_slack(scene: Scene) -> float:
    """The slack (mm) planners add to the safety margin: ``SLACK_FRACTION`` of the scene's
    diagonal."""
    return SLACK_FRACTION * scene.diagonal


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
        return self.scene.safety_margin + planning_slack(self.scene)

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


def shortcut(scene: Scene, path, rng: np.random.Generator | None = None,
             random_tries: int = DEFAULT_RANDOM_SHORTCUTS, margin: float | None = None
             ) -> np.ndarray:
    """Shorten a clear polyline ``(n, 3)``, keeping it clear (exact check at ``margin``,
    default the scene's safety margin).

    Greedy pass: from each kept vertex jump to the farthest later vertex it sees
    (``planning.search.farthest_visible``). Then ``random_tries`` seeded random shortcuts
    between two points anywhere on the path (vertices or inside segments), each kept only if
    the connecting segment is clear (``planning.search.shortcut_chords``).
    """
    margin = scene.safety_margin if margin is None else margin
    path = dedupe(np.asarray(path, dtype=float))

    def clear(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return scene.segments_clear(a, b, margin)

    path = farthest_visible(path, clear)
    if rng is None or random_tries <= 0:
        return path
    return shortcut_chords(path, clear, rng, random_tries)
