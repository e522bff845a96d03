"""PI resolved-rate tracking of the 9-DOF arm (paper 003): kinematics, limits, a short PI-HGSO
tuning, the No PI row at the paper's scale, the default controller, seeds and bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.jacobian import PositionJacobian
from kinematics.library import builtin_model
from planning.tracking import (
    DEFAULT_GAINS,
    NO_PI_GAINS,
    TUNERS,
    UNTUNED_PI_GAINS,
    EllipseTask,
    GainBounds,
    LineTask,
    PIGains,
    TrackingConfig,
    default_start,
    simulate,
    tracking_fitness,
    tune_gains,
)
from planning.tracking.stats import (
    PAPER_SCALE_CONFIG,
    PAPER_SCALE_CONTROLLER,
    PAPER_SCALE_TASKS,
)

ARM = builtin_model("hyper_redundant_9dof")
#: A short HGSO run: Table 2's population (50) for 3 iterations instead of 50 (already
#: some 50 times better than the untuned PI, 23 times better than No PI and 70 times worse
#: than the default controller on both tasks: the tests below ask for 10 times).
SHORT = 3


@pytest.fixture(scope="module")
def hgso_runs():
    """PI-HGSO, short run, on both tasks: task name -> (tuning result, recorded simulation)."""
    out = {}
    for task in (LineTask(), EllipseTask()):
        tuned = tune_gains(ARM, task, "hgso", 0, iterations=SHORT)
        out[task.kind] = (task, tuned, simulate(ARM, task, tuned.gains))
    return out


def test_default_start_is_bent_and_inside_the_reach():
    q0 = default_start(ARM)
    np.testing.assert_allclose(q0[1::2], np.radians(30.0))
    p, J = PositionJacobian(ARM)(q0[None])
    assert np.linalg.norm(p) < 0.9 * 1241.08
    assert np.linalg.svd(J[0], compute_uv=False)[-1] > 200.0  # mm/rad: far from singular


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["line", "ellipse"])
def test_pi_hgso_short_run_tunes_eq_24(hgso_runs, kind):
    """The tuner's fitness is eq. 24 of its gains, and tuning beats both baselines: the
    untuned PI and No PI (the open-loop law, which involves no gains of ours). Our tasks
    are not the paper's (it prints no sizes), so its Table 3 values are compared at its
    scale below and in benchmarks/bench_papers.py, not here."""
    task, tuned, sim = hgso_runs[kind]
    # The mean tool error along the path, recomputed from the recorded joint path by fk.
    fk_error = np.linalg.norm(sim.x_desired - fk(ARM, sim.q[0])[:, :3, 3], axis=1)
    assert tuned.fitness == pytest.approx(fk_error.mean(), rel=1e-9)
    untuned = simulate(ARM, task, UNTUNED_PI_GAINS, record=False)
    assert untuned.mean_error[0] > 10 * sim.mean_error[0]
    no_pi = simulate(ARM, task, NO_PI_GAINS, controller="default", record=False)
    assert no_pi.mean_error[0] > 10 * sim.mean_error[0]


def test_no_pi_is_the_open_loop_drift_and_halves_with_the_step():
    """No PI maps the desired velocity alone: its error is the drift of integrating at the
    control step, first order in the step (so it halves when the step does)."""
    task = PAPER_SCALE_TASKS["ellipse"]
    e = [simulate(ARM, task, NO_PI_GAINS, controller="default",
                  config=TrackingConfig(dt=dt), record=False).mean_error[0]
         for dt in (0.1, 0.05, 0.025)]
    assert e[1] / e[0] == pytest.approx(0.5, abs=0.02)
    assert e[2] / e[1] == pytest.approx(0.5, abs=0.02)


#: Table 3's No PI row, metres (not in tests/data/paper_tables.json).
PAPER_NO_PI = {"line": {"max": 1.42e-3, "mean": 1.11e-3},
               "curve": {"max": 1.61e-3, "mean": 1.12e-3}}


def test_no_pi_row_at_the_papers_scale(capsys):
    """Table 3's No PI row (line 1.11 / 1.42 mm, curve 1.12 / 1.61 mm, mean / max) at the
    paper's joint speeds (its Fig. 7: peaks of 0.025 rad/s on the line, 0.03 rad/s on the
    curve) and a 0.1 s step. The curve lands at the paper's magnitude (within a factor 1.5);
    the line does not: even 600 mm, the longest line we ran in reach at that speed, drifts
    half as much. The paper prints neither its sizes nor its step."""
    res = {k: simulate(ARM, t, NO_PI_GAINS, controller=PAPER_SCALE_CONTROLLER,
                       config=PAPER_SCALE_CONFIG) for k, t in PAPER_SCALE_TASKS.items()}
    with capsys.disabled():
        print("\nNo PI at the paper's scale: " + ", ".join(
            f"{k} {r.mean_error[0]:.3f} / {r.max_error[0]:.3f} mm at "
            f"{r.joint_speed_max[0]:.4f} rad/s" for k, r in res.items()))
    assert res["line"].joint_speed_max[0] == pytest.approx(0.025, rel=0.02)
    assert res["ellipse"].joint_speed_max[0] == pytest.approx(0.03, rel=0.02)
    assert all(r.saturated_steps[0] == 0 for r in res.values())
    curve = PAPER_NO_PI["curve"]
    for ours, printed in ((res["ellipse"].mean_error[0], curve["mean"]),
                          (res["ellipse"].max_error[0], curve["max"])):
        assert 1 / 1.5 <= ours / (1e3 * printed) <= 1.5
    line = PAPER_NO_PI["line"]
    assert 0.4 < res["line"].mean_error[0] / (1e3 * line["mean"]) < 0.6


@pytest.mark.parametrize("kind", ["line", "ellipse"])
def test_joint_speeds_and_angles_stay_within_limits(hgso_runs, kind):
    _, _, sim = hgso_runs[kind]
    assert np.abs(sim.qd).max() <= 0.1 + 1e-12
    assert np.all(sim.q >= ARM.lower) and np.all(sim.q <= ARM.upper)
    assert sim.saturated_steps[0] == 0  # the tasks are sized to need ~0.03 rad/s


@pytest.mark.parametrize("kind", ["line", "ellipse"])
def test_default_controller_beats_tuned_pi(hgso_runs, kind):
    task, tuned, sim = hgso_runs[kind]
    d = simulate(ARM, task, DEFAULT_GAINS, controller="default")
    print(f"\n{kind}: max error default {d.max_error[0]:.6f} mm vs PI-HGSO "
          f"{sim.max_error[0]:.6f} mm; mean {d.mean_error[0]:.6f} vs {sim.mean_error[0]:.6f}")
    assert d.max_error[0] < sim.max_error[0] / 10
    assert d.mean_error[0] < sim.mean_error[0] / 10
    assert np.abs(d.qd).max() <= 0.1 + 1e-12


def test_speed_limit_scales_the_whole_rate_vector():
    task = LineTask(length=200.0, duration=5.0)  # asks for ~0.12 rad/s
    slow = simulate(ARM, task, DEFAULT_GAINS, controller="default",
                    config=TrackingConfig(speed_limit=0.02))
    assert slow.saturated_steps[0] > 0
    assert np.abs(slow.qd).max() == pytest.approx(0.02)
    free = simulate(ARM, task, DEFAULT_GAINS, controller="default",
                    config=TrackingConfig(speed_limit=10.0))
    # Scaled, not clipped per joint: the first step's rates point the same way.
    a, b = slow.qd[0, 1], free.qd[0, 1]
    assert abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b)) == pytest.approx(1.0)


def test_joint_limit_weights_keep_a_joint_off_its_limit():
    q0 = default_start(ARM)
    q0[1] = ARM.upper[1] - 0.05  # joint 2 near its upper limit
    task = LineTask(length=150.0, direction=(0.0, -1.0, 0.0), duration=20.0)  # reach out
    sim = simulate(ARM, task, DEFAULT_GAINS, controller="default",
                   config=TrackingConfig(q0=tuple(q0)))
    assert np.all(sim.q <= ARM.upper) and np.all(sim.q >= ARM.lower)
    assert sim.q[0, :, 1].max() < ARM.upper[1]


def test_population_is_simulated_as_independent_runs():
    gains = [UNTUNED_PI_GAINS, PIGains((2.0, 8.0), 30.0), DEFAULT_GAINS]
    task = EllipseTask(duration=10.0)
    batch = simulate(ARM, task, gains)
    for i, g in enumerate(gains):
        one = simulate(ARM, task, g)
        np.testing.assert_allclose(batch.error[i], one.error[0], atol=1e-9)
        np.testing.assert_allclose(batch.q[i], one.q[0], atol=1e-12)


def test_population_fitness_is_eq_24_per_candidate():
    """One batched call rates a population of 50; each value is eq. 24 of that candidate's
    own run (its time goal is benchmarks/bench_speed_goals.py's)."""
    task = LineTask(duration=5.0)
    f = tracking_fitness(ARM, task)
    X = np.random.default_rng(0).uniform(GainBounds().lower, GainBounds().upper, (50, 3))
    F = f(X)
    assert F.shape == (50,) and np.all(np.isfinite(F)) and np.all(F > 0)
    assert len(np.unique(F)) == 50  # different gains, different errors
    for i in (0, 17, 49):
        sim = simulate(ARM, task, PIGains((X[i, 0], X[i, 1]), X[i, 2]))
        fk_error = np.linalg.norm(sim.x_desired - fk(ARM, sim.q[0])[:, :3, 3], axis=1)
        assert F[i] == pytest.approx(fk_error.mean(), rel=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("tuner", sorted(TUNERS))
def test_tuning_is_reproducible_by_seed(tuner):
    task = LineTask(duration=5.0)
    a = tune_gains(ARM, task, tuner, 7, iterations=2)
    b = tune_gains(ARM, task, tuner, 7, iterations=2)
    c = tune_gains(ARM, task, tuner, 8, iterations=2)
    assert a.gains == b.gains and a.fitness == b.fitness
    np.testing.assert_array_equal(a.optim.history, b.optim.history)
    assert a.gains != c.gains
    lo, hi = GainBounds().lower, GainBounds().upper
    assert np.all(a.gains.as_vector() >= lo) and np.all(a.gains.as_vector() <= hi)


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: LineTask(length=-1.0), "length"),
        (lambda: LineTask(direction=(0.0, 0.0, 0.0)), "direction"),
        (lambda: LineTask(duration=float("nan")), "duration"),
        (lambda: EllipseTask(radii=(150.0, 0.0)), "radii"),
        (lambda: EllipseTask(normal=(0.0, 0.0, 1.0), major=(0.0, 0.0, 2.0)), "major"),
        (lambda: PIGains((-1.0, 1.0), 1.0), "kp"),
        (lambda: PIGains((1.0, 1.0), -1.0), "ki"),
        (lambda: GainBounds(kp=(-1.0, 2.0)), "kp"),
        (lambda: GainBounds(ki=(5.0, 5.0)), "ki"),
        (lambda: TrackingConfig(dt=0.0), "dt"),
        (lambda: TrackingConfig(speed_limit=-0.1), "speed_limit"),
        (lambda: simulate(ARM, LineTask(), DEFAULT_GAINS, controller="pid"), "controller"),
        (lambda: simulate(ARM, LineTask(), DEFAULT_GAINS,
                          config=TrackingConfig(q0=(0.0,) * 8)), "q0"),
        (lambda: simulate(ARM, LineTask(), DEFAULT_GAINS,
                          config=TrackingConfig(q0=(3.0,) * 9)), "q0"),
        (lambda: simulate(ARM, LineTask(), np.ones((4, 2))), "gains"),
        (lambda: tune_gains(ARM, LineTask(), "simplex"), "tune"),
    ],
)
def test_bad_inputs_raise_value_error_naming_the_field(make, field):
    with pytest.raises(ValueError, match=field):
        make()
