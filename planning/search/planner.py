"""``SamplingPlanner``: the base of a tool-path planner that samples, run by
``planning.paths.plan_path`` through this core.

A subclass is a frozen dataclass of the planner's parameters (the registry's knobs: every
number with its caps in the field metadata) and implements ``search``. Registered in the
``path`` family of ``planning.registry`` (``register("path", name, TheClass,
shared=ShortcutParams)``), it is a ``plan_path`` algorithm like any other: ``plan_path``
builds the scene's box as a ``BoxSpace`` (steps of ``STEP_FRACTION`` of the scene's
diagonal, segments tested exactly at the safety margin plus the planning slack), calls
``search`` and then verifies and shortens the path it returns, as for every planner.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .result import SearchResult
from .space import BoxSpace

__all__ = ["SamplingPlanner", "STEP_FRACTION"]

#: Longest step of the box space ``plan_path`` hands a sampling planner, as a fraction of the
#: scene's diagonal.
STEP_FRACTION = 0.1


class SamplingPlanner:
    """Base of a sampling-based tool-path planner (module docstring)."""

    def search(self, space: BoxSpace, start: np.ndarray, goal: np.ndarray,
               rng: np.random.Generator,
               progress: Callable[[float], None] | None = None) -> SearchResult:
        """A path ``(K, dim)`` from ``start`` to ``goal`` in ``space`` with every segment
        free by ``space.segments_free``, or None with a failed status (``budget_spent``,
        ``no_path``); ``stats["nodes"]`` counts the samples it kept. Draw every random
        number from ``rng``; ``progress(fraction)`` may raise to stop."""
        raise NotImplementedError
