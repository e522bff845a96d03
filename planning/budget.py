"""What every iterative search keeps: an evaluation budget, the best point so far, the
convergence history and progress reports.

The continuous optimisers (``planning.optimisers``: points ``(P, D)`` scored by the
problem's objective) and the hole sequencers (``planning.sequencing``: orders ``(B, n)``
scored by their path lengths) both run under a ``Budget``. An algorithm calls
``evaluate(batch)`` for the scores and ``end_iteration()`` after each iteration;
``run(body)`` runs it until it returns or the budget is spent. A progress callback receives
the fraction done and may raise to stop the run (that is how jobs are cancelled).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Generic, TypeVar

import numpy as np

__all__ = ["Budget", "BudgetExhausted", "ProgressFn"]

ProgressFn = Callable[[float], None]
P = TypeVar("P")


class BudgetExhausted(Exception):
    """Raised by ``Budget.evaluate`` once the evaluation budget is spent."""


class Budget(Generic[P]):
    """Counts evaluations of ``problem`` (scored by ``score: (B, ...) -> (B,)``, lower is
    better, NaN and inf count as inf), keeps the best item and the history of best scores,
    and reports progress.

    ``max_evaluations``: the budget (None: unlimited). ``iterations``: with a number,
    progress is the fraction of those iterations ended (reported by ``end_iteration``);
    without, the fraction of the budget spent (reported by ``evaluate``). An item replaces
    the best only if it beats it by more than ``improve_tol``. ``dtype``: the items' element
    type (float points, int orders). ``partial_batch_ends_iteration``: a batch the budget
    cuts short also closes the iteration (its best enters the history).
    """

    def __init__(self, problem: P, score: Callable[[np.ndarray], np.ndarray], *,
                 max_evaluations: int | None = None, progress: ProgressFn | None = None,
                 iterations: int | None = None, improve_tol: float = 0.0,
                 dtype: type = float, partial_batch_ends_iteration: bool = False) -> None:
        self.problem = problem
        self.score = score
        self.max_evaluations = max_evaluations
        self.progress = progress
        self.iterations = None if iterations is None else max(1, int(iterations))
        self.improve_tol = improve_tol
        self.dtype = dtype
        self.partial_batch_ends_iteration = partial_batch_ends_iteration
        self.evaluations = 0
        self.best: np.ndarray | None = None
        self.best_value = math.inf
        self.history: list[float] = []
        self.started = time.perf_counter()
        #: Whether ``run`` ended because the evaluation budget was spent.
        self.spent = False

    @property
    def elapsed_s(self) -> float:
        """Seconds since the budget was created."""
        return time.perf_counter() - self.started

    def offer(self, item: np.ndarray, value: float) -> None:
        """Record an item whose score is already known (no evaluation counted)."""
        if value < self.best_value - self.improve_tol:
            self.best_value, self.best = float(value), np.array(item, dtype=self.dtype)

    def evaluate(self, batch: np.ndarray) -> np.ndarray:
        """Scores ``(B,)`` of ``batch (B, ...)``, counted against the budget.

        If the budget cannot cover the whole batch, the part that fits is still scored (so
        its best item counts) and ``BudgetExhausted`` is raised: callers never get fewer
        scores than they asked for.
        """
        batch = np.atleast_2d(np.asarray(batch, dtype=self.dtype))
        room = len(batch) if self.max_evaluations is None else \
            self.max_evaluations - self.evaluations
        if room <= 0:
            raise BudgetExhausted()
        part = batch[:room]
        F = np.asarray(self.score(part), dtype=float).reshape(-1)
        F = np.where(np.isfinite(F), F, np.inf)
        self.evaluations += len(part)
        k = int(np.argmin(F))
        self.offer(part[k], float(F[k]))
        if self.iterations is None and self.progress is not None and self.max_evaluations:
            self.progress(min(1.0, self.evaluations / self.max_evaluations))
        if len(part) < len(batch):
            if self.partial_batch_ends_iteration:
                self.history.append(self.best_value)
            raise BudgetExhausted()
        return F

    def end_iteration(self) -> None:
        """Append the best score so far to the history (and, counting iterations, report
        progress)."""
        self.history.append(self.best_value)
        if self.iterations is not None and self.progress is not None:
            self.progress(min(1.0, len(self.history) / self.iterations))

    def run(self, body: Callable[[], str | None]) -> str:
        """Run ``body()`` until it returns or the budget is spent; its message (default
        ``"finished"``) or ``"evaluation budget spent"``."""
        try:
            return body() or "finished"
        except BudgetExhausted:
            self.spent = True
            return "evaluation budget spent"
