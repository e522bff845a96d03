"""Joint-space RRT-Connect: the baseline paper 002 compares IAPF with (section 4.2).

Kuffner and LaValle's RRT-Connect (ICRA 2000) in the arm's normalised transfer space
(``space.ArmSpace``): two trees, from the start and from the goal; each iteration extends one
tree one ``step`` towards a uniform random sample and then greedily connects the other tree
to the new node; the trees swap roles every iteration. An edge is free when the arm keeps
``safety`` mm from every obstacle at points ``edge_resolution`` apart along it (the final
10 ms check of the smoothed trajectory is the guarantee). The raw path is what the paper's
baseline smooths; ``shortcut`` > 0 adds that many random shortcut attempts (off by default,
so the comparison is with a plain RRT).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinematics.errors import FieldError

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
        trees = [([us], [-1]), ([ug], [-1])]
        for it in range(self.max_iterations):
            a, b = trees[it % 2], trees[(it + 1) % 2]
            target = rng.random(3)
            new = self._extend(space, obstacles, a, target, margin)
            if new is None:
                continue
            joint = self._connect(space, obstacles, b, a[0][new], margin)
            if joint is not None:
                start_tree, goal_tree = (a, b) if it % 2 == 0 else (b, a)
                i_s, i_g = (new, joint) if it % 2 == 0 else (joint, new)
                path = self._trace(start_tree, i_s)[::-1] + self._trace(goal_tree, i_g)[1:]
                P = np.array(path)
                P = self._shortcut(space, obstacles, P, margin, rng)
                min_c = float(space.clearance(space.from_u(P), obstacles).min())
                return MovePath(space.from_u(P), PlanStatus.OK, "connected", min_c, it + 1,
                                  "rrt",
                                  {"nodes": len(trees[0][0]) + len(trees[1][0])})
        return MovePath(space.from_u(us[None]), PlanStatus.BUDGET_SPENT,
                          f"no connection in {self.max_iterations} iterations",
                          float(c.min()), self.max_iterations, "rrt")

    # ---- tree operations ---------------------------------------------------------------
    def _edge_free(self, space, obstacles, u0, u1, margin) -> bool:
        n = max(1, int(np.ceil(np.linalg.norm(u1 - u0) / self.edge_resolution)))
        pts = u0 + np.linspace(0.0, 1.0, n + 1)[1:, None] * (u1 - u0)
        return bool(space.clearance(space.from_u(pts), obstacles).min() >= margin)

    def _extend(self, space, obstacles, tree, target, margin) -> int | None:
        nodes, parents = tree
        N = np.asarray(nodes)
        i = int(np.argmin(np.linalg.norm(N - target, axis=1)))
        d = target - N[i]
        dist = float(np.linalg.norm(d))
        if dist < 1e-12:
            return i
        new = N[i] + d * min(1.0, self.step / dist)
        if not self._edge_free(space, obstacles, N[i], new, margin):
            return None
        nodes.append(new)
        parents.append(i)
        return len(nodes) - 1

    def _connect(self, space, obstacles, tree, target, margin) -> int | None:
        """Extend ``tree`` towards ``target`` until it gets there (its node index) or is
        blocked (None)."""
        while True:
            k = self._extend(space, obstacles, tree, target, margin)
            if k is None:
                return None
            if np.linalg.norm(tree[0][k] - target) < 1e-9:
                return k

    @staticmethod
    def _trace(tree, i) -> list[np.ndarray]:
        nodes, parents = tree
        out = []
        while i >= 0:
            out.append(nodes[i])
            i = parents[i]
        return out

    def _shortcut(self, space, obstacles, P, margin, rng) -> np.ndarray:
        P = list(P)
        for _ in range(self.shortcut):
            if len(P) < 3:
                break
            i, j = sorted(rng.choice(len(P), size=2, replace=False))
            if j - i < 2:
                continue
            if self._edge_free(space, obstacles, P[i], P[j], margin):
                P = P[: i + 1] + P[j:]
        return np.array(P)
