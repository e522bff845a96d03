"""Joint-space RRT-Connect: the baseline paper 002 compares IAPF with (section 4.2).

Kuffner and LaValle's RRT-Connect (ICRA 2000, ``planning.search.rrt_connect``) in the arm's
normalised transfer space (``space.ArmSpace``): two trees, from the start and from the goal;
each iteration extends one tree one ``step`` towards a uniform random sample and then
greedily connects the other tree to the new node; the trees swap roles every iteration. An
edge is free when the arm keeps ``safety`` mm from every obstacle at points
``edge_resolution`` apart along it (the final 10 ms check of the smoothed trajectory is the
guarantee). The raw path is what the paper's baseline smooths; ``shortcut`` > 0 adds that
many random shortcut attempts between waypoints (``planning.search.shortcut_vertices``; off
by default, so the comparison is with a plain RRT).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinematics.errors import FieldError

from ..search import Tree, iteration_budget, rrt_connect, shortcut_vertices
from ..status import PlanStatus
from .iapf import MovePath
from .space import ArmSpace, Obstacles

__all__ = ["RRTConnect"]


@dataclass(frozen=True)
class RRTConnect:
    """RRT-Connect parameters (normalised units; ``safety`` mm)."""

    step: float = field(default=0.05, metadata={"ge": 1e-4, "le": 1.0, "description": "normalised"})
    edge_resolution: float = field(default=0.005, metadata={
        "ge": 1e-4, "le": 1.0, "description": "normalised"})
    max_iterations: int = field(default=3000, metadata={"ge": 1, "le": 100_000})
    safety: float = field(default=100.0, metadata={"ge": 0.0, "le": 2000.0, "description": "mm"})
    shortcut: int = field(default=0, metadata={"ge": 0, "le": 10_000})

    def __post_init__(self) -> None:
        for name in ("step", "edge_resolution"):
            if not getattr(self, name) > 0:
                raise FieldError(("planner_params", name),
                                 f"planner_params.{name}: must be positive")
        if self.max_iterations < 1:
            raise FieldError(("planner_params", "max_iterations"),
                             "planner_params.max_iterations: must be >= 1")
        for name in ("shortcut", "safety"):
            if getattr(self, name) < 0:
                raise FieldError(("planner_params", name), f"planner_params.{name}: must be >= 0")

    def plan(self, space: ArmSpace, obstacles: Obstacles, q_start, q_goal,
             rng: np.random.Generator) -> MovePath:
        """Path of the planned joints from ``q_start (3,)`` to ``q_goal (3,)``."""
        us = space.to_u(np.asarray(q_start, dtype=float)[None])[0]
        ug = space.to_u(np.asarray(q_goal, dtype=float)[None])[0]
        c = space.clearance(space.from_u(np.array([us, ug])), obstacles)
        for k, end in ((1, "goal"), (0, "start")):
            if c[k] == -np.inf:  # how ``ArmSpace.clearance`` marks leaving the joint limits
                return MovePath(space.from_u(us[None]), PlanStatus.INVALID_INPUT,
                                  f"{end} configuration leaves the joint limits", float(c[k]),
                                  0, "rrt")
            if c[k] < 0:
                return MovePath(space.from_u(us[None]), PlanStatus.COLLISION,
                                  f"{end} configuration collides", float(c[k]), 0, "rrt")
        margin = min(self.safety, float(c.min()))
        search = _TransferSpace(self, space, obstacles, margin)
        res = rrt_connect(search, us, ug, rng, iteration_budget(self.max_iterations))
        if res.path is not None:
            P = shortcut_vertices(res.path, search.segment_free, rng, self.shortcut)
            min_c = float(space.clearance(space.from_u(P), obstacles).min())
            return MovePath(space.from_u(P), PlanStatus.OK, "connected", min_c,
                            res.stats["iterations"], "rrt", {"nodes": res.stats["nodes"]})
        return MovePath(space.from_u(us[None]), PlanStatus.BUDGET_SPENT,
                          f"no connection in {self.max_iterations} iterations",
                          float(c.min()), self.max_iterations, "rrt")


class _TransferSpace:
    """The normalised transfer space as a ``planning.search`` space: samples
    ``rng.random(3)``, the Euclidean metric, steps of ``step``, edges free when the arm
    keeps ``margin`` mm at points ``edge_resolution`` apart."""

    def __init__(self, planner: RRTConnect, space: ArmSpace, obstacles: Obstacles,
                 margin: float) -> None:
        self.planner, self.space, self.obstacles, self.margin = planner, space, obstacles, margin

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        return rng.random(3)

    def nearest(self, tree: Tree, x: np.ndarray) -> int:
        return int(np.argmin(np.linalg.norm(tree.nodes - x, axis=1)))

    def steer(self, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray | None, bool]:
        d = b - a
        dist = float(np.linalg.norm(d))
        if dist < 1e-12:
            return None, True
        new = a + d * min(1.0, self.planner.step / dist)
        return new, bool(np.linalg.norm(new - b) < 1e-9)

    def segment_free(self, u0: np.ndarray, u1: np.ndarray) -> bool:
        n = max(1, int(np.ceil(np.linalg.norm(u1 - u0) / self.planner.edge_resolution)))
        pts = u0 + np.linspace(0.0, 1.0, n + 1)[1:, None] * (u1 - u0)
        clearance = self.space.clearance(self.space.from_u(pts), self.obstacles)
        return bool(clearance.min() >= self.margin)
