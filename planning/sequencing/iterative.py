"""What the iterative sequencers share: their run under a ``planning.budget.Budget``
(evaluations, best order, history, progress) and the base class that solves tiny problems
exactly."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..budget import Budget, ProgressFn
from .base import IMPROVE_EPS, SequenceResult, SequencingProblem
from .exact import held_karp

__all__ = ["Budget", "IterativeSequencer", "run_sequencing", "sequencing_budget"]


def sequencing_budget(problem: SequencingProblem, iterations: int,
                      progress: ProgressFn | None = None,
                      max_evaluations: int | None = None) -> Budget[SequencingProblem]:
    """The budget of one sequencer run: orders ``(B, n)`` scored by their path lengths,
    raising ``BudgetExhausted`` once ``max_evaluations`` is spent (after scoring what fits);
    ``end_iteration()`` appends the best-so-far to the history and calls
    ``progress(iteration / iterations)``, which may raise to stop the run (job
    cancellation). A shorter order replaces the best only if it is shorter by more than
    ``IMPROVE_EPS``."""
    return Budget(problem, problem.lengths, max_evaluations=max_evaluations,
                  progress=progress, iterations=iterations, improve_tol=IMPROVE_EPS,
                  dtype=int)


def run_sequencing(budget: Budget[SequencingProblem], body: Callable[[], str | None],
                   algorithm: str) -> SequenceResult:
    """Run ``body()`` (which returns a message) until it ends or the budget is spent; the
    best order found, as hole indices."""
    message = budget.run(body)
    if budget.best is None:
        raise ValueError("the sequencer evaluated nothing")
    return SequenceResult(
        order=budget.problem.hole_order(budget.best), length=budget.best_value,
        history=np.array(budget.history), runtime_s=budget.elapsed_s,
        evaluations=budget.evaluations, iterations=len(budget.history), algorithm=algorithm,
        message=message, budget_spent=budget.spent,
    )


class IterativeSequencer:
    """Base of the iterative sequencers: ``solve`` runs the subclass's ``_body(problem, rng,
    budget)`` for ``self.iterations`` generations under ``sequencing_budget`` (budget,
    progress, history); ``name`` labels the result. Problems of three holes or fewer are solved
    exactly instead (a population has nothing to search there)."""

    name = "sequencer"
    #: Problems up to this many holes are solved by ``held_karp`` instead of ``_body``.
    EXACT_UP_TO = 3

    def solve(self, problem: SequencingProblem, rng: np.random.Generator, *,
              progress: ProgressFn | None = None,
              max_evaluations: int | None = None) -> SequenceResult:
        """Run the algorithm; the result's ``history`` has one entry per generation."""
        tr = sequencing_budget(problem, self.iterations,  # type: ignore[attr-defined]
                               progress, max_evaluations)

        def body() -> str:
            if problem.n <= self.EXACT_UP_TO:
                return self._exact(problem, tr)
            return self._body(problem, rng, tr)  # type: ignore[attr-defined]

        return run_sequencing(tr, body, self.name)

    @staticmethod
    def _exact(problem: SequencingProblem, tr: Budget[SequencingProblem]) -> str:
        order, _ = held_karp(problem)
        tr.evaluate(order[None])
        tr.end_iteration()
        return "solved exactly (3 holes or fewer to order)"
