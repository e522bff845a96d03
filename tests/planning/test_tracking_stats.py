"""Paper 003's Table 3 statistics (``planning.tracking.stats``) on a short run: repeated
tunings by seed, worst-case max, mean of eq. 24, mean error fluctuation, the rank-sum test
against untuned PI, progress, and the table's layout next to the paper's values."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.tracking import NO_PI_GAINS, UNTUNED_PI_GAINS, LineTask, simulate, tune_gains
from planning.tracking.stats import TrackingTable, TunerStats, format_table3, tracking_table

ARM = builtin_model("hyper_redundant_9dof")
TASK = LineTask(length=100.0, duration=5.0)
RUNS = 4
ITERATIONS = 3


@pytest.fixture(scope="module")
def table_and_progress():
    seen: list[float] = []
    table = tracking_table(ARM, TASK, ("pso", "gwo"), runs=RUNS, seed=4,
                           iterations=ITERATIONS, progress=seen.append)
    return table, seen


def fk_errors(gains) -> np.ndarray:
    """Tool error along TASK for ``gains``, mm per sample: the recorded joint path put
    through ``fk`` and compared with the desired path (not the simulation's own errors)."""
    sim = simulate(ARM, TASK, gains)
    return np.linalg.norm(sim.x_desired - fk(ARM, sim.q[0])[:, :3, 3], axis=1)


@pytest.mark.slow
def test_rows_hold_one_tuning_per_seed(table_and_progress):
    table, _ = table_and_progress
    assert table.task == "line" and [r.name for r in table.rows] == ["pso", "gwo"]
    pso = table.rows[0]
    assert pso.fitness.shape == pso.run_max.shape == pso.run_std.shape == (RUNS,)
    assert len(pso.gains) == RUNS and len(set(pso.gains)) == RUNS  # one tuning per seed
    # run r is the tuning with seed 4 + r ...
    assert pso.gains[2] == tune_gains(ARM, TASK, "pso", 4 + 2, iterations=ITERATIONS).gains
    # ... and its columns are eq. 24, the worst and the spread of its tool errors
    err = fk_errors(pso.gains[2])
    assert pso.fitness[2] == pytest.approx(err.mean(), rel=1e-9)
    assert pso.run_max[2] == pytest.approx(err.max(), rel=1e-9)
    assert pso.run_std[2] == pytest.approx(err.std(), rel=1e-9)


def test_summary_columns_are_the_papers():
    """Hand-made runs: max is the worst step of any run, mean the mean of the runs' eq. 24
    values, std the mean of the runs' fluctuations, best_run the lowest eq. 24."""
    row = TunerStats("x", np.array([0.25, 0.5, 0.5, 0.75]), np.array([1.0, 3.5, 0.75, 0.25]),
                     np.array([0.1, 0.2, 0.3, 0.2]), ())
    assert row.max == 3.5
    assert row.mean == pytest.approx(0.5)
    assert row.std == pytest.approx(0.2)
    assert row.best_run == 0


@pytest.mark.slow
def test_untuned_pi_row_repeats_one_deterministic_run(table_and_progress):
    table, _ = table_and_progress
    base = table.baseline
    err = fk_errors(UNTUNED_PI_GAINS)
    np.testing.assert_allclose(base.fitness, np.full(RUNS, err.mean()), rtol=1e-9)
    np.testing.assert_allclose(base.run_max, np.full(RUNS, err.max()), rtol=1e-9)
    assert base.gains == (UNTUNED_PI_GAINS,) * RUNS
    assert base.p_value is None


@pytest.mark.slow
def test_no_pi_row_is_the_open_loop_law(table_and_progress):
    """Table 3's "No PI": the desired velocity alone through eq. 13 (zero gains on the
    feed-forward law), one deterministic run repeated: no gains of ours in it."""
    table, _ = table_and_progress
    row = table.no_pi
    assert row.name == "no_pi" and row.gains == (NO_PI_GAINS,) * RUNS
    sim = simulate(ARM, TASK, NO_PI_GAINS, controller="default")
    err = np.linalg.norm(sim.x_desired - fk(ARM, sim.q[0])[:, :3, 3], axis=1)
    np.testing.assert_allclose(row.fitness, np.full(RUNS, err.mean()), rtol=1e-9)
    np.testing.assert_allclose(row.run_max, np.full(RUNS, err.max()), rtol=1e-9)
    assert row.p_value is None and row.p_no_pi is None


@pytest.mark.slow
def test_rank_sum_finds_every_tuner_better_than_no_pi(table_and_progress):
    """Against the baseline that has no gains of ours (the untuned PI's gains are our pick,
    so beating it says little): every tuning, even 3 iterations long, beats No PI."""
    table, _ = table_and_progress
    for row in table.rows:
        assert row.fitness.max() < table.no_pi.fitness.min()
        # 4 against 4 with no overlap: rank sum W = 1 + ... + 4 = 10 against a mean of
        # 4 * 9 / 2 = 18 and a variance of 4 * 4 * 9 / 12 = 12, z = -8 / sqrt(12) = -2.309,
        # two-sided p = 2 * Phi(-2.309) = 0.02092 (the normal approximation)
        assert row.p_no_pi == pytest.approx(0.02092, abs=5e-5)
        assert row.sign(table.no_pi, row.p_no_pi) == "+"


def test_sign_is_minus_when_worse_and_equals_when_not_significant():
    base = TunerStats("pi", np.ones(6), np.ones(6), np.ones(6), ())
    worse = TunerStats("x", np.full(6, 2.0), np.ones(6), np.ones(6), (), p_value=0.004)
    unclear = TunerStats("y", np.full(6, 0.5), np.ones(6), np.ones(6), (), p_value=0.2)
    assert worse.sign(base) == "-" and unclear.sign(base) == "="


def test_progress_rises_to_one(table_and_progress):
    _, seen = table_and_progress
    assert seen and seen == sorted(seen) and seen[-1] == pytest.approx(1.0)


def test_format_table3_converts_the_papers_metres():
    """Hand-made rows whose columns are worked out by hand: PI-PSO's max 1 mm is 3 mm below
    PI's 4 mm, its mean 0.5 mm is 75 % below PI's 2 mm; PI-GWO is 2 mm and 50 % worse."""
    base = TunerStats("pi", np.full(4, 2.0), np.full(4, 4.0), np.full(4, 0.5), ())
    pso = TunerStats("pso", np.array([0.25, 0.5, 0.5, 0.75]), np.array([1.0, 0.5, 0.75, 0.25]),
                     np.array([0.1, 0.2, 0.3, 0.2]), (), p_value=0.004)
    gwo = TunerStats("gwo", np.full(4, 3.0), np.array([5.0, 6.0, 5.5, 5.0]), np.ones(4), (),
                     p_value=0.2)
    table = TrackingTable("line", base, (pso, gwo))
    paper = {"PI-PSO": {"max": 8.42e-3, "mean": 2.75e-3, "std": 7.32e-4}}
    lines = format_table3(table, paper).splitlines()
    assert len(lines) == 1 + 1 + 2  # header, PI, two tuners (no No PI row given)
    assert lines[0].split()[:10] == ["line", "algorithm", "max", "variation", "mean",
                                     "percent", "std", "ranksum", "p", "|"]
    assert lines[1].split() == ["PI", "4.0000", "/", "2.0000", "/", "0.5000", "/",
                                "|", "-", "-", "-"]
    assert lines[2].split() == ["PI-PSO", "1.0000", "3.0000", "0.5000", "75.00%", "0.2000",
                                "+", "0.004", "|", "8.42", "2.75", "0.732"]  # metres -> mm
    assert lines[3].split() == ["PI-GWO", "6.0000", "-2.0000", "3.0000", "-50.00%", "1.0000",
                                "=", "0.2", "|", "-", "-", "-"]  # no paper value given
    assert "paper" in lines[0]
    plain = format_table3(table).splitlines()
    assert "paper" not in plain[0] and "|" not in "".join(plain)
    assert plain[2].split() == lines[2].split()[:8]
    # With a No PI row it comes first, laid out like PI's.
    no_pi = TunerStats("no_pi", np.full(4, 2.5), np.full(4, 5.0), np.full(4, 0.25), ())
    with_row = format_table3(TrackingTable("line", base, (pso, gwo), no_pi)).splitlines()
    assert len(with_row) == 1 + 2 + 2
    assert with_row[1].split() == ["No", "PI", "5.0000", "/", "2.5000", "/", "0.2500", "/"]
    assert with_row[2:] == plain[1:]


def test_runs_must_be_positive():
    with pytest.raises(ValueError, match="runs"):
        tracking_table(ARM, TASK, ("pso",), runs=0)
