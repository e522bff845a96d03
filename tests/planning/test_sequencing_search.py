"""The compiled local search behind ``auto`` (``planning.sequencing.oropt``): candidate lists,
local optima checked move by move against the exhaustive dense moves of ``local``, the
bookkeeping of every applied move, reproducibility per seed, and the time and evaluation
budgets (a fake clock, no wall-clock asserts)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planning.sequencing import Auto, SequencingProblem, held_karp, sequence_holes
from planning.sequencing.auto import default_time_limit, engine_for, improve_order
from planning.sequencing.candidates import nearest_by_costs, nearest_by_points
from planning.sequencing.local import or_opt_move, two_opt_move


def random_face(n: int, seed: int) -> np.ndarray:
    """``n`` holes on the face plane x = 9000 mm, 10 m x 7 m, seeded."""
    rng = np.random.default_rng(seed)
    return np.c_[np.full(n, 9000.0), rng.uniform(-5000, 5000, n), rng.uniform(-3500, 3500, n)]


def extended(problem: SequencingProblem, order) -> np.ndarray:
    """The open path with both ends, as ``local``'s exhaustive moves take it."""
    return np.concatenate([[problem.n], np.asarray(order), [problem.n + 1]])


# ---- candidate lists ---------------------------------------------------------------------------
def test_candidates_are_the_nearest_in_order():
    X = random_face(60, 1)
    D = np.linalg.norm(X[:, None] - X[None], axis=-1)
    brute = np.argsort(D + np.diag(np.full(60, np.inf)), axis=1, kind="stable")[:, :8]
    assert np.array_equal(nearest_by_points(X, 8), brute)
    assert np.array_equal(nearest_by_costs(D, 8), brute)
    # never itself, at most n - 1, even with a point on top of another
    Y = np.vstack([X[:5], X[:1]])
    nb = nearest_by_points(Y, 10)
    assert nb.shape == (6, 5) and not (nb == np.arange(6)[:, None]).any()


# ---- local optima ------------------------------------------------------------------------------
@pytest.mark.parametrize("lk_depth", [0, 6])
def test_the_descent_ends_in_a_2opt_and_or_opt_local_optimum(lk_depth):
    """With complete candidate lists no improving 2-opt move (any reversal) and no improving
    Or-opt move (any segment of 1-3 holes, either way round, anywhere) is left: checked
    exhaustively by the dense moves of ``local``, after a descent and after kicks."""
    for seed in range(12):
        H = random_face(int(8 + 3 * seed), seed)
        p = SequencingProblem.from_holes(H, [9000, 0, -4000] if seed % 2 else None)
        eng = engine_for(p, neighbours=p.n, seed=seed, lk_depth=lk_depth)
        start = eng.length
        eng.descend()
        assert eng.length < start
        for _ in range(3):
            T = extended(p, eng.best_order())
            assert two_opt_move(p.E, T)[0] > -1e-7
            assert or_opt_move(p.E, T, 3)[0] > -1e-7
            eng.kick(40)
            eng.polish()


def test_auto_answers_a_local_optimum_with_short_candidate_lists():
    """``auto``'s answer with 10 candidates per hole: no 2-opt move breaking an edge at a
    hole and making an edge to one of its candidates improves it (the moves the lists
    allow), checked by brute force over all reversals."""
    H = random_face(90, 3)
    p = SequencingProblem.from_holes(H, [9000, 0, -4000])
    res = sequence_holes(H, [9000, 0, -4000], "auto", seed=1, params={"kicks": 300})
    T = extended(p, p.free_order(res.order))
    E = p.E
    n = p.n
    nbr = nearest_by_points(p.points, 10)
    allowed = np.zeros((n + 2, n + 2), dtype=bool)
    for a in range(n + 1):
        allowed[a, nbr[a]] = True
    allowed |= allowed.T
    for i, j in itertools.combinations(range(1, n + 1), 2):
        a, b, c, d = T[i - 1], T[i], T[j], T[j + 1]
        delta = E[a, c] + E[b, d] - E[a, b] - E[c, d]
        if allowed[a, c] or allowed[b, d]:
            assert delta > -1e-7, (i, j, delta)


def test_every_applied_move_changes_the_cost_by_what_it_claimed():
    """The descent's claimed total change equals the exact change (Euclidean points and a
    cost table alike), kicks keep a permutation and the tracked cost, for any kick span."""
    rng = np.random.default_rng(7)
    for trial in range(20):
        n = int(rng.integers(6, 80))
        H = random_face(n + 1, 100 + trial)
        p = SequencingProblem.from_holes(H)
        q = SequencingProblem.from_costs(
            np.linalg.norm(H[:, None] - H[None], axis=-1))
        for prob in (p, q):
            eng = engine_for(prob, neighbours=int(rng.integers(2, 12)), seed=trial,
                             order=rng.permutation(prob.n))
            before = eng.length
            eng.descend()
            assert before + eng.predicted == pytest.approx(eng.length, abs=1e-6)
            for _ in range(3):
                eng.kick(30, span=int(rng.integers(3, 50)))
                order = eng.order()
                assert sorted(order.tolist()) == list(range(prob.n))
                assert eng.cost_of(order) == pytest.approx(eng.length, abs=1e-6)
                assert prob.length(order) == pytest.approx(eng.length, abs=1e-6)


def test_a_cost_table_is_solved_like_points():
    """``from_costs``: node 0 the start, any symmetric table; ``auto`` finds the exact
    optimum of a small one with its local search alone."""
    for seed in range(3):
        H = random_face(11, 40 + seed)
        C = np.linalg.norm(H[:, None] - H[None], axis=-1) ** 1.2  # not Euclidean
        p = SequencingProblem.from_costs(C)
        _, best = held_karp(p)
        res = Auto(exact_max=0).solve(p, np.random.default_rng(seed))
        assert res.order[0] == 0 and sorted(res.order.tolist()) == list(range(11))
        assert res.length == pytest.approx(best, rel=1e-9)
    with pytest.raises(ValueError, match="symmetric"):
        SequencingProblem.from_costs([[0, 1], [2, 0]])


def test_improve_order_never_lengthens():
    H = random_face(120, 5)
    p = SequencingProblem.from_holes(H, [9000, 0, -4000])
    start = np.random.default_rng(0).permutation(p.n)
    better = improve_order(p, start, kicks=500, seed=3)
    assert sorted(better.tolist()) == list(range(p.n))
    assert p.length(better) < p.length(start)
    assert p.length(improve_order(p, better, kicks=0, seed=3)) <= p.length(better) + 1e-9


# ---- reproducibility and budgets -----------------------------------------------------------
def test_the_same_seed_gives_the_same_order():
    H = random_face(300, 11)
    a = sequence_holes(H, [9000, 0, -4000], "auto", seed=4, params={"kicks": 3000})
    b = sequence_holes(H, [9000, 0, -4000], "auto", seed=4, params={"kicks": 3000})
    c = sequence_holes(H, [9000, 0, -4000], "auto", seed=5, params={"kicks": 3000})
    assert np.array_equal(a.order, b.order) and a.length == b.length
    assert a.extra["stopped"] == "kicks" and a.extra["kicks"] == 3000
    assert sorted(c.order.tolist()) == list(range(300))
    assert a.history[-1] == pytest.approx(a.length)
    assert np.all(np.diff(a.history) <= 1e-9)


def test_the_time_limit_is_honoured(fake_clock):
    """Time is read between compiled chunks: with a clock that jumps 1 s per reading and a
    3 s limit, the search stops after a few chunks, says so, and still answers with a
    valid, locally optimal order."""
    H = random_face(400, 12)
    p = SequencingProblem.from_holes(H, [9000, 0, -4000])
    clock = fake_clock(1.0)
    res = Auto(time_limit=3.0).solve(p, np.random.default_rng(0), clock=clock)
    assert res.extra["stopped"] == "time limit" and "time limit" in res.message
    assert 0 < res.extra["kicks"] <= 3 * 256 * 4
    assert sorted(res.order.tolist()) == list(range(400))
    assert clock.t < 20  # read a handful of times, not once per kick
    # with a limit that does not bind, the kick budget ends the same search at the same
    # place: the course does not depend on how the kicks were split into chunks
    same = Auto(kicks=res.extra["kicks"], time_limit=3600.0).solve(
        p, np.random.default_rng(0), clock=fake_clock(1e-3))
    assert same.extra["stopped"] == "kicks"
    assert np.array_equal(same.order, res.order)


def test_the_evaluation_budget_is_honoured():
    H = random_face(200, 13)
    res = sequence_holes(H, None, "auto", seed=0, max_evaluations=700)
    assert res.evaluations == 700 and res.budget_spent
    assert res.extra["stopped"] == "evaluations"
    assert sorted(res.order.tolist()) == list(range(200))


def test_progress_is_reported_and_can_cancel():
    H = random_face(150, 14)
    seen: list[float] = []
    sequence_holes(H, None, "auto", seed=0, params={"kicks": 5000}, progress=seen.append)
    assert seen and seen == sorted(seen) and 0 < seen[-1] <= 1.0

    class Stop(Exception):
        pass

    def cancel(f):
        raise Stop

    with pytest.raises(Stop):
        sequence_holes(H, None, "auto", seed=0, progress=cancel)


def test_default_budgets_scale_with_the_face():
    # the speed goals (1 s for 200 holes, 5 s for 1,000, 20 s for 2,000) with 5 % to spare
    assert default_time_limit(200) == pytest.approx(0.95)
    assert default_time_limit(1000) == pytest.approx(4.75)
    assert default_time_limit(2000) == pytest.approx(19.0)
    assert default_time_limit(20) == 0.5 and default_time_limit(5000) == 60.0
    a = Auto()
    assert a.kick_budget(1000) == 100_000 and a.stall_budget(1000) == 10_000
    assert Auto(kicks=7, stall=3).kick_budget(1000) == 7


@pytest.mark.parametrize(("params", "field"), [
    ({"kick_span": 2}, "params.kick_span"), ({"lk_depth": -1}, "params.lk_depth"),
    ({"neighbours": 1}, "params.neighbours"), ({"time_limit": 0.0}, "params.time_limit"),
    ({"stall": 0}, "params.stall"),
])
def test_bad_knobs_name_the_field(params, field):
    from planning.sequencing import make_sequencer

    with pytest.raises(ValueError, match=field):
        make_sequencer("auto", params)
