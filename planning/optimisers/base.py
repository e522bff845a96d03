"""The interface every metaheuristic in kinoplan implements.

An optimiser minimises a *batched* objective over a box: ``f(X: (P, D)) -> (P,)``, so a
whole population is evaluated in one vectorised call. Every run takes a seeded
``numpy.random.Generator``, stops at an evaluation budget, and returns the best point with
its convergence history (best-so-far after each iteration). A progress callback receives the
fraction of the budget used and may raise to stop the run (that is how jobs are cancelled).

An optimiser module provides a frozen dataclass of its parameters (defaults = the paper's)
with a ``minimize(problem, rng, *, max_evaluations=None, progress=None) -> OptimResult``
method. ``run_with_budget`` wraps the objective so budget accounting and the history are
kept in one place, not re-implemented per algorithm.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Problem", "OptimResult", "ProgressFn", "BudgetExhausted", "Evaluator",
           "Optimiser", "run_with_budget"]

ProgressFn = Callable[[float], None]


@dataclass(frozen=True)
class Problem:
    """Minimise ``f`` over ``lower <= x <= upper`` (``(D,)`` each). ``f: (P, D) -> (P,)``."""

    f: Callable[[np.ndarray], np.ndarray]
    lower: np.ndarray
    upper: np.ndarray

    @property
    def dim(self) -> int:
        return int(np.asarray(self.lower).shape[0])

    def clip(self, X: np.ndarray) -> np.ndarray:
        return np.clip(X, self.lower, self.upper)

    def uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """``n`` points uniformly in the box ``(n, D)``."""
        return rng.uniform(self.lower, self.upper, size=(n, self.dim))


@dataclass(frozen=True)
class OptimResult:
    """Best point ``x (D,)`` and value; ``history`` = best-so-far after each iteration."""

    x: np.ndarray
    fun: float
    evaluations: int
    iterations: int
    history: np.ndarray
    runtime_s: float
    message: str = ""
    extra: dict = field(default_factory=dict)


class BudgetExhausted(Exception):
    """Raised by ``Evaluator`` once the evaluation budget is spent."""


class Evaluator:
    """Counts evaluations of a problem, tracks the best point, and reports progress.

    Algorithms call ``evaluate(X)``; once ``max_evaluations`` is reached the call evaluates
    only what fits and then raises ``BudgetExhausted`` (caught by ``run_with_budget``).
    ``end_iteration()`` appends the best-so-far to the history.
    """

    def __init__(self, problem: Problem, max_evaluations: int | None,
                 progress: ProgressFn | None) -> None:
        self.problem = problem
        self.max_evaluations = max_evaluations
        self.progress = progress
        self.evaluations = 0
        self.best_x: np.ndarray | None = None
        self.best_f = np.inf
        self.history: list[float] = []

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Objective values ``(P,)`` of points ``X (P, D)`` (non-finite values become inf).

        If the budget cannot cover all of ``X``, the part that fits is still evaluated (so
        its best point counts) and ``BudgetExhausted`` is raised: callers never get a
        shorter array than they asked for.
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        room = len(X) if self.max_evaluations is None else \
            self.max_evaluations - self.evaluations
        if room <= 0:
            raise BudgetExhausted()
        part = X[:room]
        F = np.asarray(self.problem.f(part), dtype=float).reshape(-1)
        F = np.where(np.isfinite(F), F, np.inf)
        self.evaluations += len(part)
        k = int(np.argmin(F))
        if F[k] < self.best_f:
            self.best_f, self.best_x = float(F[k]), part[k].copy()
        if self.progress is not None and self.max_evaluations:
            self.progress(min(1.0, self.evaluations / self.max_evaluations))
        if len(part) < len(X):
            self.history.append(self.best_f)
            raise BudgetExhausted()
        return F

    def end_iteration(self) -> None:
        self.history.append(self.best_f)


def run_with_budget(
    problem: Problem,
    body: Callable[[Evaluator], str | None],
    *,
    max_evaluations: int | None = None,
    progress: ProgressFn | None = None,
) -> OptimResult:
    """Run an algorithm's ``body(evaluator)`` until it returns or the budget is spent.

    ``body`` returns an optional message. The result holds the best point ever evaluated.
    """
    ev = Evaluator(problem, max_evaluations, progress)
    t0 = time.perf_counter()
    try:
        message = body(ev) or "finished"
    except BudgetExhausted:
        message = "evaluation budget spent"
    if ev.best_x is None:
        raise ValueError("the optimiser evaluated nothing")
    return OptimResult(
        x=ev.best_x, fun=ev.best_f, evaluations=ev.evaluations, iterations=len(ev.history),
        history=np.array(ev.history), runtime_s=time.perf_counter() - t0, message=message,
    )


class Optimiser:
    """Base of the optimiser classes: ``minimize`` runs the subclass's ``_run(evaluator,
    rng)`` under the budget (``_run`` returns an optional message)."""

    def minimize(self, problem: Problem, rng: np.random.Generator, *,
                 max_evaluations: int | None = None,
                 progress: ProgressFn | None = None) -> OptimResult:
        """Minimise ``problem`` with ``rng`` as the only source of randomness."""
        return run_with_budget(problem, lambda ev: self._run(ev, rng),  # type: ignore[attr-defined]
                               max_evaluations=max_evaluations, progress=progress)
