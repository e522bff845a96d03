"""Joint trajectories: paper 004's quintic and sextic, paper 002's quintic B-spline."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.library import builtin_model
from planning import Limits, plan_trajectory, quintic_segments, sextic_via
from planning.trajectories.bspline import paper_control_points, paper_evaluate, quintic_bspline
from planning.trajectories.time_scaling import fit_to_limits


@pytest.fixture
def glt_abc(paper_tables):
    rows = paper_tables["glt_palletizer"]["key_points_table4"]
    return np.radians([row["q_deg"] for row in rows])


def test_quintic_matches_eq21_closed_form(glt_abc):
    """Eq. 21 (2 s per segment): q(t) = q_A + d (5/4 t^3 - 15/16 t^4 + 3/16 t^5)."""
    traj = quintic_segments(glt_abc, [2.0, 2.0])
    t = np.linspace(0.0, 2.0, 201)
    for k in range(2):
        d = glt_abc[k + 1] - glt_abc[k]
        expected = glt_abc[k] + np.outer(5 / 4 * t**3 - 15 / 16 * t**4 + 3 / 16 * t**5, d)
        np.testing.assert_allclose(traj.evaluate(2.0 * k + t), expected, atol=1e-12, rtol=0)
    # At rest at A, B and C: zero velocity and acceleration.
    for m in (1, 2):
        np.testing.assert_allclose(traj.evaluate([0.0, 2.0, 4.0], m), 0.0, atol=1e-12)


def test_quintic_stop_at_b_has_a_jerk_jump_only(glt_abc):
    c = quintic_segments(glt_abc, [2.0, 2.0]).continuity()
    assert c["position"] < 1e-12 and c["velocity"] < 1e-12 and c["acceleration"] < 1e-12
    assert c["jerk"] > 1e-3  # two separate quintics: jerk is not continuous at B


def test_sextic_passes_b_without_stopping(glt_abc):
    traj = sextic_via(glt_abc, [2.0, 2.0])
    np.testing.assert_allclose(traj.evaluate([0.0, 2.0, 4.0]), glt_abc, atol=1e-12)
    np.testing.assert_allclose(traj.evaluate([0.0, 4.0], 1), 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.evaluate([0.0, 4.0], 2), 0.0, atol=1e-12)
    moving = np.abs(glt_abc[2] - glt_abc[0]) > 1e-6
    assert np.all(np.abs(traj.evaluate([2.0], 1)[0][moving]) > 1e-3)  # does not stop at B
    c = traj.continuity()
    assert max(c.values()) < 1e-9


@pytest.mark.parametrize("method", ["quintic", "sextic", "bspline5", "smooth"])
def test_paper_004_moves_stay_within_glt_limits(glt_abc, method):
    glt = builtin_model("glt_palletizer")
    traj = plan_trajectory(method, glt_abc, [2.0, 2.0])
    lo, hi = traj.range()
    assert np.all(lo >= glt.lower) and np.all(hi <= glt.upper)
    assert not traj.violations(Limits(lower=glt.lower, upper=glt.upper))


def test_given_waypoint_rates_are_met():
    q = np.array([[0.0, 0.0], [1.0, -1.0], [0.5, 2.0]])
    v = np.array([[0.0, 0.0], [0.3, 0.1], [0.0, 0.0]])
    a = np.array([[0.0, 0.0], [-0.2, 0.4], [0.0, 0.0]])
    traj = quintic_segments(q, [1.5, 2.5], v, a)
    np.testing.assert_allclose(traj.evaluate([0.0, 1.5, 4.0]), q, atol=1e-12)
    np.testing.assert_allclose(traj.evaluate([0.0, 1.5, 4.0], 1), v, atol=1e-12)
    np.testing.assert_allclose(traj.evaluate([0.0, 1.5, 4.0], 2), a, atol=1e-12)
    assert traj.continuity()["acceleration"] < 1e-12


def test_bspline_agrees_with_the_papers_basis_matrix():
    """Eq. 14's basis with eqs. 15/17/18's system solved directly = our scipy spline."""
    P = np.random.default_rng(0).uniform(-2, 2, (6, 4))
    traj = quintic_bspline(P, np.ones(5))
    N = paper_control_points(P)
    t = np.linspace(0.0, 5.0, 251)
    for m in range(4):
        np.testing.assert_allclose(traj.evaluate(t, m), paper_evaluate(N, t, m), atol=1e-10)
    # Eq. 16: at the joins position, velocity, acceleration and jerk agree.
    assert max(traj.continuity().values()) < 1e-9


def test_paper_002_middle_arm_move(paper_tables, capsys):
    """The middle arm from (10025, 907, 614) to (9000, -3877, 6595) mm with Table 3's joint
    values. The paper gives neither the intermediate points nor the duration: we take three
    intermediate points on the straight joint-space line and 5 s per segment, and compare the
    peak joint acceleration (revolute joints) with the paper's 'below 0.25 rad/s^2'."""
    rows = paper_tables["tunnel_drill_arm"]["table3"]
    keys = ["theta1_deg", "theta2_deg", "d3_mm", "theta5_deg", "theta6_deg"]
    revolute = np.array([True, True, False, True, True])

    def joints(row):
        v = np.array([row["q"][k] for k in keys], dtype=float)
        return np.where(revolute, np.radians(v), v)

    start, goal = joints(rows[0]), joints(rows[1])
    path = start + np.linspace(0.0, 1.0, 5)[:, None] * (goal - start)
    traj = quintic_bspline(path, [5.0] * 4)
    c = traj.continuity()
    assert max(c.values()) < 1e-9
    for m in (1, 2):  # at rest at both ends (d3 is in mm, thousands: round-off ~1e-12)
        np.testing.assert_allclose(traj.evaluate([0.0, traj.duration], m), 0.0, atol=1e-9)
    np.testing.assert_allclose(traj.evaluate([0.0, traj.duration]), [start, goal], atol=1e-9)
    peak_acc = traj.peaks(2)[0][revolute].max()
    fitted = fit_to_limits(traj, Limits(acceleration=np.where(revolute, 0.25, np.inf)),
                           per_segment=False)
    with capsys.disabled():
        print(f"\npaper 002 middle arm, 4 x 5 s B-spline: peak revolute joint acceleration "
              f"{peak_acc:.4f} rad/s^2 (paper: below 0.25); shortest duration at 0.25 rad/s^2: "
              f"{fitted.duration:.2f} s")
    assert peak_acc < 0.25
    assert fitted.peaks(2)[0][revolute].max() == pytest.approx(0.25, rel=0.01)


@pytest.mark.parametrize("method", ["quintic", "sextic", "bspline5"])
@pytest.mark.parametrize("quantity", ["velocity", "acceleration", "jerk"])
def test_time_scaling_meets_the_limit(glt_abc, method, quantity):
    traj = plan_trajectory(method, glt_abc, [0.5, 0.5])  # far too fast
    lim = {"velocity": 0.4, "acceleration": 0.8, "jerk": 3.0}[quantity]
    limits = Limits(**{quantity: np.full(6, lim)})
    m = {"velocity": 1, "acceleration": 2, "jerk": 3}[quantity]
    assert traj.violations(limits)
    fitted = fit_to_limits(traj, limits, per_segment=method == "quintic")
    assert not fitted.violations(Limits(**{quantity: np.full(6, lim * 1.0001)}))
    peak = fitted.peaks(m)[0].max()
    assert peak == pytest.approx(lim, rel=0.01)
    # The path is unchanged: same waypoints in the same order.
    np.testing.assert_allclose(fitted.evaluate(fitted.breaks[fitted.waypoint_index]), glt_abc,
                               atol=1e-9)


def test_time_scaling_needs_a_rate_limit(glt_abc):
    with pytest.raises(ValueError, match="limits"):
        fit_to_limits(plan_trajectory("quintic", glt_abc, [1, 1]), Limits(), per_segment=True)


@pytest.mark.parametrize(
    "waypoints, durations, field",
    [
        ([[0.0, 1.0]], [], "waypoints"),
        ([[0.0], [1.0]], [1.0, 2.0], "durations"),
        ([[0.0], [1.0]], [0.0], "durations"),
        ([[0.0], [np.nan]], [1.0], "waypoints"),
    ],
)
def test_bad_input_names_the_field(waypoints, durations, field):
    with pytest.raises(ValueError, match=field):
        plan_trajectory("quintic", waypoints, durations)


def test_sampling_includes_the_end_and_caps_the_count(glt_abc):
    traj = plan_trajectory("quintic", glt_abc, [2.0, 2.0])
    s = traj.sample(0.3)
    assert s.t[0] == 0.0 and s.t[-1] == pytest.approx(4.0)
    assert s.q.shape == (len(s.t), 6)
    with pytest.raises(ValueError, match="samples"):
        traj.sample(1e-6)


@settings(max_examples=30, deadline=None, derandomize=True, database=None)
@given(
    st.integers(3, 8),
    st.integers(1, 4),
    st.lists(st.floats(0.2, 5.0), min_size=7, max_size=7),
    st.integers(0, 1000),
)
def test_splines_are_c4_through_their_waypoints(n, dof, durations, seed):
    q = np.random.default_rng(seed).uniform(-3, 3, (n, dof))
    for method in ("bspline5", "smooth"):
        traj = plan_trajectory(method, q, durations[: n - 1])
        times = np.concatenate([[0.0], np.cumsum(durations[: n - 1])])
        np.testing.assert_allclose(traj.evaluate(times), q, atol=1e-8)
        c = traj.continuity()
        scale = 1.0 + np.abs(q).max() / min(durations[: n - 1]) ** 3
        assert c["jerk"] < 1e-7 * scale
