"""Paper 003's Table 3 statistics (``planning.tracking_stats``) on a short run: repeated
tunings by seed, worst-case max, mean of eq. 24, mean error fluctuation, the rank-sum test
against untuned PI, progress, and the table's layout next to the paper's values."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.library import builtin_model
from planning.tracking import UNTUNED_PI_GAINS, LineTask, simulate, tune_gains
from planning.tracking_stats import TunerStats, format_table3, tracking_table

ARM = builtin_model("hyper_redundant_9dof")
TASK = LineTask(length=100.0, duration=5.0)
RUNS = 6
ITERATIONS = 3


@pytest.fixture(scope="module")
def table_and_progress():
    seen: list[float] = []
    table = tracking_table(ARM, TASK, ("pso", "gwo"), runs=RUNS, seed=4,
                           iterations=ITERATIONS, progress=seen.append)
    return table, seen


def test_rows_hold_one_tuning_per_seed(table_and_progress):
    table, _ = table_and_progress
    assert table.task == "line" and [r.name for r in table.rows] == ["pso", "gwo"]
    pso = table.rows[0]
    assert pso.fitness.shape == pso.run_max.shape == pso.run_std.shape == (RUNS,)
    # run r is the tuning with seed 4 + r, simulated again
    again = tune_gains(ARM, TASK, "pso", 4 + 2, iterations=ITERATIONS).gains
    assert pso.gains[2] == again
    sim = simulate(ARM, TASK, again)
    assert pso.fitness[2] == pytest.approx(sim.mean_error[0], rel=1e-12)
    assert pso.run_max[2] == pytest.approx(sim.max_error[0], rel=1e-12)
    assert pso.run_std[2] == pytest.approx(sim.std_error[0], rel=1e-12)


def test_summary_columns_are_the_papers(table_and_progress):
    table, _ = table_and_progress
    for row in (table.baseline, *table.rows):
        assert row.max == row.run_max.max()  # worst case over every step of every run
        assert row.mean == pytest.approx(row.fitness.mean())  # mean of eq. 24
        assert row.std == pytest.approx(row.run_std.mean())  # mean fluctuation
    # untuned PI is deterministic: all its runs are the same simulation
    base = simulate(ARM, TASK, UNTUNED_PI_GAINS)
    np.testing.assert_allclose(table.baseline.fitness, base.mean_error[0], rtol=1e-12)
    assert table.baseline.p_value is None


def test_rank_sum_finds_every_tuner_better_than_untuned_pi(table_and_progress):
    table, _ = table_and_progress
    for row in table.rows:
        assert row.fitness.max() < table.baseline.fitness.min()
        # 6 against 6 with no overlap: the smallest two-sided p the normal approximation
        # gives for these sizes, about 0.004
        assert row.p_value == pytest.approx(0.0039, abs=5e-4)
        assert row.sign(table.baseline) == "+"


def test_sign_is_minus_when_worse_and_equals_when_not_significant():
    base = TunerStats("pi", np.ones(6), np.ones(6), np.ones(6), ())
    worse = TunerStats("x", np.full(6, 2.0), np.ones(6), np.ones(6), (), p_value=0.004)
    unclear = TunerStats("y", np.full(6, 0.5), np.ones(6), np.ones(6), (), p_value=0.2)
    assert worse.sign(base) == "-" and unclear.sign(base) == "="


def test_progress_rises_to_one(table_and_progress):
    _, seen = table_and_progress
    assert seen and seen == sorted(seen) and seen[-1] == pytest.approx(1.0)


def test_format_table3_converts_the_papers_metres(table_and_progress):
    table, _ = table_and_progress
    text = format_table3(table, {"PI-PSO": {"max": 8.42e-3, "mean": 2.75e-3, "std": 7.32e-4}})
    lines = text.splitlines()
    assert len(lines) == 1 + 1 + 2  # header, PI, two tuners
    assert lines[1].split()[0] == "PI" and lines[2].split()[0] == "PI-PSO"
    b, pso = table.baseline, table.rows[0]
    pct = 100.0 * (b.mean - pso.mean) / b.mean
    assert f"{pct:8.2f}%" in lines[2]
    assert f"{b.max - pso.max:11.4f}" in lines[2]  # Table 3's "variation"
    assert lines[2].rstrip().endswith("8.42     2.75    0.732")  # metres -> mm
    assert lines[3].rstrip().endswith("-        -        -")  # no paper value given
    assert "paper" in lines[0]
    assert "paper" not in format_table3(table).splitlines()[0]


def test_runs_must_be_positive():
    with pytest.raises(ValueError, match="runs"):
        tracking_table(ARM, TASK, ("pso",), runs=0)
