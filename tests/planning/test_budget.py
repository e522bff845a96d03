"""``planning.budget.Budget``: the one budget / best-so-far / history / progress contract
that the continuous optimisers and the hole sequencers both run under."""

from __future__ import annotations

import numpy as np
import pytest

from planning.budget import Budget, BudgetExhausted
from planning.optimisers.base import Problem, evaluation_budget, run_with_budget
from planning.sequencing import SequencingProblem, sequence_holes
from planning.sequencing.iterative import run_sequencing, sequencing_budget


def _sum_of_squares(X: np.ndarray) -> np.ndarray:
    return (X**2).sum(axis=1)


def test_the_best_item_and_its_score_are_kept():
    b = Budget(None, _sum_of_squares)
    F = b.evaluate([[3.0, 0.0], [1.0, 1.0], [2.0, 2.0]])
    np.testing.assert_array_equal(F, [9.0, 2.0, 8.0])
    b.evaluate([[0.0, 2.0]])  # worse than the best: ignored
    assert b.evaluations == 4 and b.best_value == 2.0
    np.testing.assert_array_equal(b.best, [1.0, 1.0])
    item = np.array([[0.5, 0.5]])
    b.evaluate(item)
    item[0, 0] = 99.0  # the budget keeps its own copy
    np.testing.assert_array_equal(b.best, [0.5, 0.5])


def test_nan_and_infinite_scores_count_as_infinite():
    b = Budget(None, lambda X: np.array([np.nan, -np.inf, 1.0]))
    np.testing.assert_array_equal(b.evaluate(np.zeros((3, 1))), [np.inf, np.inf, 1.0])
    assert b.best_value == 1.0


def test_a_batch_the_budget_cuts_short_is_scored_as_far_as_it_fits():
    b = Budget(None, _sum_of_squares, max_evaluations=3)
    b.evaluate([[1.0], [2.0]])
    with pytest.raises(BudgetExhausted):
        b.evaluate([[3.0], [0.5], [0.1]])  # room for one: [3.0]
    assert b.evaluations == 3 and b.best_value == 1.0
    with pytest.raises(BudgetExhausted):
        b.evaluate([[0.0]])
    assert b.evaluations == 3 and b.history == []


def test_a_cut_batch_can_close_its_iteration():
    b = Budget(None, _sum_of_squares, max_evaluations=3, partial_batch_ends_iteration=True)
    b.evaluate([[2.0]])
    b.end_iteration()
    with pytest.raises(BudgetExhausted):
        b.evaluate([[1.0], [0.5], [3.0]])
    assert b.history == [4.0, 0.25]


def test_an_improvement_must_beat_the_tolerance():
    b = Budget(None, lambda X: X[:, 0], improve_tol=0.1, dtype=int)
    b.evaluate([[5], [7]])
    b.evaluate([[5]])  # a tie
    b.offer(np.array([9]), 4.95)  # better by less than the tolerance
    assert b.best_value == 5.0 and b.best.tolist() == [5] and b.best.dtype.kind == "i"
    b.offer(np.array([8]), 4.8)
    assert b.best_value == 4.8 and b.best.tolist() == [8]
    assert b.evaluations == 3  # offers are not evaluations


def test_progress_counts_evaluations_or_iterations():
    seen: list[float] = []
    b = Budget(None, _sum_of_squares, max_evaluations=4, progress=seen.append)
    b.evaluate([[1.0]])
    b.end_iteration()  # counting evaluations: no report here
    b.evaluate([[1.0], [2.0]])
    assert seen == [0.25, 0.75]
    seen.clear()
    b = Budget(None, _sum_of_squares, max_evaluations=4, progress=seen.append, iterations=2)
    b.evaluate([[1.0], [2.0], [3.0]])
    b.end_iteration()
    b.end_iteration()
    b.end_iteration()
    assert seen == [0.5, 1.0, 1.0] and b.history == [1.0, 1.0, 1.0]


def test_a_progress_callback_that_raises_stops_the_run():
    def cancel(fraction: float) -> None:
        raise RuntimeError("cancelled")

    b = Budget(None, _sum_of_squares, max_evaluations=10, progress=cancel)
    with pytest.raises(RuntimeError, match="cancelled"):
        b.run(lambda: str(b.evaluate([[1.0]])))


def test_run_reports_how_the_body_ended():
    b = Budget(None, _sum_of_squares, max_evaluations=1)
    assert b.run(lambda: "converged") == "converged"
    assert b.run(lambda: None) == "finished"

    def greedy() -> str:
        while True:
            b.evaluate([[1.0]])

    assert not b.spent
    assert b.run(greedy) == "evaluation budget spent"
    assert b.spent
    assert b.elapsed_s >= 0.0


def test_optimisers_and_sequencers_run_under_the_same_budget():
    box = Problem(_sum_of_squares, np.full(2, -1.0), np.full(2, 1.0))
    opt = evaluation_budget(box, 10)
    holes = np.array([[0.0, 0, 0], [0, 100, 0], [0, 50, 0], [0, 10, 0]])
    seq = sequencing_budget(SequencingProblem.from_holes(holes), iterations=5)
    assert type(opt) is type(seq) is Budget
    assert opt.problem is box and opt.partial_batch_ends_iteration and opt.iterations is None
    assert seq.iterations == 5 and seq.improve_tol > 0 and seq.dtype is int

    seen: list[Budget] = []

    def body(ev: Budget) -> str:
        seen.append(ev)
        ev.evaluate([[0.5, 0.5], [0.1, 0.0]])
        ev.end_iteration()
        return "done"

    out = run_with_budget(box, body, max_evaluations=5)
    assert isinstance(seen[0], Budget)
    assert out.message == "done" and out.evaluations == 2 and out.fun == pytest.approx(0.01)
    np.testing.assert_array_equal(out.x, [0.1, 0.0])
    np.testing.assert_array_equal(out.history, [pytest.approx(0.01)])


def test_a_sequencing_run_reports_hole_indices_and_its_history():
    holes = np.array([[0.0, 0, 0], [0, 100, 0], [0, 50, 0], [0, 10, 0]])
    problem = SequencingProblem.from_holes(holes)  # hole 0 is the start
    budget = sequencing_budget(problem, iterations=2)

    def body() -> str:
        budget.evaluate(np.array([[0, 1, 2], [2, 1, 0]]))  # free nodes 0..2 = holes 1..3
        budget.end_iteration()
        return "two orders"

    res = run_sequencing(budget, body, "test")
    assert res.order.tolist() == [0, 3, 2, 1] and res.length == pytest.approx(100.0)
    assert res.history.tolist() == [pytest.approx(100.0)] and res.iterations == 1
    assert res.evaluations == 2 and res.algorithm == "test" and res.message == "two orders"
    with pytest.raises(ValueError, match="evaluated nothing"):
        run_sequencing(sequencing_budget(problem, 1), lambda: "idle", "test")


def test_a_sequencer_stops_at_its_evaluation_budget():
    rng = np.random.default_rng(0)
    holes = np.c_[np.full(30, 9000.0), rng.uniform(-3000, 3000, 30), rng.uniform(0, 6000, 30)]
    res = sequence_holes(holes, None, "aco", 1, {"iterations": 50}, max_evaluations=137)
    assert res.evaluations == 137 and res.message == "evaluation budget spent"
    assert res.budget_spent
    assert len(res.history) == res.iterations < 50
