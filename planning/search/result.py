"""What every search of ``planning.search`` returns, and the stop rules it takes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..status import PlanStatus

__all__ = ["SearchResult", "Stop", "iteration_budget"]

#: Called once before each iteration; True ends the search.
Stop = Callable[[], bool]


def iteration_budget(iterations: int) -> Stop:
    """A stop rule that lets a search run ``iterations`` iterations."""
    left = [int(iterations)]

    def stop() -> bool:
        if left[0] <= 0:
            return True
        left[0] -= 1
        return False

    return stop


@dataclass
class SearchResult:
    """A search's answer. ``path (K, dim)`` from a start to a goal, every segment free at
    the space's final resolution, or None; ``status``: ``ok`` with a path, else
    ``budget_spent`` (the stop rule ended the search first); ``stats``: counts of the run
    (``iterations``, ``nodes`` ...); ``history``: the best cost at regular intervals (RRT*)."""

    path: np.ndarray | None
    status: PlanStatus
    stats: dict = field(default_factory=dict)
    history: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK
