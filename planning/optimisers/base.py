"""The interface every metaheuristic in kinoplan implements.

An optimiser minimises a *batched* objective over a box: ``f(X: (P, D)) -> (P,)``, so a
whole population is evaluated in one vectorised call. Every run takes a seeded
``numpy.random.Generator``, stops at an evaluation budget, and returns the best point with
its convergence history (best-so-far after each iteration). A progress callback receives the
fraction of the budget used and may raise to stop the run (that is how jobs are cancelled).

An optimiser module provides a frozen dataclass of its parameters (defaults = the paper's)
with a ``minimize(problem, rng, *, max_evaluations=None, progress=None) -> OptimResult``
method. ``run_with_budget`` runs it under a ``planning.budget.Budget``, so budget accounting
and the history are kept in one place (shared with the hole sequencers), not re-implemented
per algorithm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..budget import Budget, BudgetExhausted, ProgressFn

__all__ = ["Problem", "OptimResult", "ProgressFn", "BudgetExhausted", "Budget",
           "Optimiser", "evaluation_budget", "run_with_budget"]


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


def evaluation_budget(problem: Problem, max_evaluations: int | None = None,
                      progress: ProgressFn | None = None) -> Budget[Problem]:
    """The budget of one optimiser run: points scored by ``problem.f``, progress as the
    fraction of ``max_evaluations`` spent, and a batch the budget cuts short still closes
    its iteration. Algorithms call ``evaluate(X)``, which scores only what fits once
    ``max_evaluations`` is reached and then raises ``BudgetExhausted`` (caught by
    ``run_with_budget``); ``end_iteration()`` appends the best-so-far to the history."""
    return Budget(problem, problem.f, max_evaluations=max_evaluations, progress=progress,
                  partial_batch_ends_iteration=True)


def run_with_budget(
    problem: Problem,
    body: Callable[[Budget[Problem]], str | None],
    *,
    max_evaluations: int | None = None,
    progress: ProgressFn | None = None,
) -> OptimResult:
    """Run an algorithm's ``body(budget)`` until it returns or the budget is spent.

    ``body`` returns an optional message. The result holds the best point ever evaluated.
    """
    ev = evaluation_budget(problem, max_evaluations, progress)
    message = ev.run(lambda: body(ev))
    if ev.best is None:
        raise ValueError("the optimiser evaluated nothing")
    return OptimResult(
        x=ev.best, fun=ev.best_value, evaluations=ev.evaluations, iterations=len(ev.history),
        history=np.array(ev.history), runtime_s=ev.elapsed_s, message=message,
    )


class Optimiser:
    """Base of the optimiser classes: ``minimize`` runs the subclass's ``_run(budget, rng)``
    under the budget (``_run`` returns an optional message)."""

    def minimize(self, problem: Problem, rng: np.random.Generator, *,
                 max_evaluations: int | None = None,
                 progress: ProgressFn | None = None) -> OptimResult:
        """Minimise ``problem`` with ``rng`` as the only source of randomness."""
        return run_with_budget(problem, lambda ev: self._run(ev, rng),  # type: ignore[attr-defined]
                               max_evaluations=max_evaluations, progress=progress)
