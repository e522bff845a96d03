"""Time-optimal path parameterisation (planning.trajectories.topp) and the hydraulic limits.

Checked against what is known without the solver: the trapezoidal and triangular speed
laws of a straight line (closed form), stops where the path turns sharply, and for the
pile driver under its pump, a brute check: no uniform speed-up of the optimum keeps the
limits, and the best uniform time law of the same path (found by bisection) is slower.
Cylinder speeds and oil flows are recomputed here from ``CylinderSet`` and the bore and rod
diameters, not taken from the module under test.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from kinematics.cylinders import CylinderSet
from kinematics.errors import FieldError
from kinematics.library import builtin_model
from planning.trajectories.hydraulic import hydraulic_limits
from planning.trajectories.joint_path import CORNER_FACTOR, JointPath, smooth_polyline
from planning.trajectories.limits_check import binding, limit_ratios
from planning.trajectories.polynomials import smooth_spline
from planning.trajectories.time_scaling import fit_optimal, path_for
from planning.trajectories.topp import ToppStatus, time_optimal
from planning.trajectories.trajectory import Limits

PILE = builtin_model("pile_driver")
NAMES = [j.name for j in PILE.joints]


def _dense(traj, n: int = 4001):
    t = np.linspace(traj.breaks[0], traj.breaks[-1], n)
    return t, traj.evaluate(t), traj.evaluate(t, 1), traj.evaluate(t, 2)


# ---- straight lines: closed-form speed laws --------------------------------------------
def test_straight_line_cruises_at_the_velocity_limit_over_its_middle():
    """Joint 1 moves 2 rad, joint 2 1 rad, on one line; v = 1, a = 2 for both. Joint 1 binds:
    a trapezoid of 0.5 s ramps and 1.5 s cruise at 1 rad/s, T = d/v + v/a = 2.5 s."""
    path = smooth_polyline([[0.0, 0.0], [2.0, 1.0]], 0.0)
    res = time_optimal(path, Limits(velocity=[1.0, 1.0], acceleration=[2.0, 2.0]))
    assert res.success and res.status is ToppStatus.OK
    assert res.duration == pytest.approx(2.5, rel=2e-3)
    t, q, qd, qdd = _dense(res.trajectory)
    middle = (t > 0.55) & (t < 1.95)
    np.testing.assert_allclose(qd[middle, 0], 1.0, rtol=2e-3)
    np.testing.assert_allclose(qd[middle, 1], 0.5, rtol=2e-3)
    ramp = (t > 0.02) & (t < 0.48)
    np.testing.assert_allclose(qdd[ramp, 0], 2.0, rtol=1e-2)
    assert np.abs(qd).max() <= 1.0 + 1e-9 and np.abs(qdd).max() <= 2.0 + 1e-6
    bound = binding(limit_ratios(q, qd, qdd, None, [1.0, 1.0], [2.0, 2.0], None, None),
                    ["j1", "j2"], None)
    assert all(b == ["j1 velocity"] for b, m in zip(bound, middle) if m)
    assert all("j1 acceleration" in b for b, r in zip(bound, ramp) if r)


def test_short_line_is_a_triangle_that_never_reaches_the_velocity_limit():
    """0.25 rad at a = 2: T = 2 sqrt(d / a) = 0.7071 s, peak sqrt(a d) = 0.7071 < v = 1."""
    path = smooth_polyline([[0.0], [0.25]], 0.0)
    res = time_optimal(path, Limits(velocity=[1.0], acceleration=[2.0]))
    assert res.duration == pytest.approx(2 * math.sqrt(0.25 / 2.0), rel=2e-3)
    _, _, qd, _ = _dense(res.trajectory)
    assert qd.max() == pytest.approx(math.sqrt(2.0 * 0.25), rel=2e-3)


def test_start_and_end_speeds_change_the_law():
    """A path speed given at the end: the line is left at rest and ends at 0.5 rad/s."""
    path = smooth_polyline([[0.0], [2.0]], 0.0)
    res = time_optimal(path, Limits(velocity=[1.0], acceleration=[1.0]), end_speed=0.5,
                       keep_limits=False)
    # 0 -> 1 rad/s in 1 s (0.5 rad), cruise, 1 -> 0.5 in 0.5 s (0.375 rad): 1.125 s cruise.
    assert res.optimal_duration == pytest.approx(1.0 + 1.125 + 0.5, rel=2e-3)
    assert math.sqrt(res.x[-1]) == pytest.approx(0.5)
    too_fast = time_optimal(path, Limits(velocity=[1.0], acceleration=[1.0]), end_speed=2.0)
    assert too_fast.status is ToppStatus.INFEASIBLE and not too_fast.success


# ---- stops and blends --------------------------------------------------------------------
def test_a_sharp_corner_and_a_reversal_are_stops():
    for points in ([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], [[0.0], [1.0], [0.4]]):
        path = smooth_polyline(points, 0.0)
        assert path.stops.tolist() == [1.0]
        res = time_optimal(path, Limits(velocity=np.ones(path.dof),
                                        acceleration=np.ones(path.dof)))
        traj = res.trajectory
        t_corner = traj.breaks[traj.waypoint_index[1]]
        np.testing.assert_allclose(traj.evaluate(np.array([t_corner])), [points[1]],
                                   atol=1e-12)
        np.testing.assert_allclose(traj.evaluate(np.array([t_corner]), 1), 0.0, atol=1e-12)
        # It moves again right after: the stop is a point, not a stretch.
        assert np.abs(traj.evaluate(np.array([t_corner + 0.1]), 1)).max() > 1e-3


def test_quintic_at_rest_is_a_polyline_with_stops_where_it_turns():
    wp = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [2.0, 1.0]]
    path = path_for("quintic", wp)
    assert path.stops.tolist() == [2.0]  # the collinear waypoint is passed at speed
    res = fit_optimal(path, Limits(velocity=[1.0, 1.0], acceleration=[1.0, 1.0]))
    traj = res.trajectory
    t = traj.breaks[traj.waypoint_index]
    speeds = np.linalg.norm(traj.evaluate(t, 1), axis=1)
    assert speeds[1] > 0.5 and speeds[2] == pytest.approx(0.0, abs=1e-12)


def test_a_blended_corner_keeps_within_its_deviation_and_does_not_stop():
    corner = np.array([1.0, 0.0])
    path = smooth_polyline([[0.0, 0.0], corner, [1.0, 1.0]], 0.05)
    assert path.stops.size == 0
    s = np.linspace(0, path.length, 20001)
    q = path.evaluate(s)
    assert np.linalg.norm(q - corner, axis=1).min() == pytest.approx(0.05, rel=1e-6)
    # C3: derivatives up to the third agree across every piece boundary.
    for m in range(4):
        left = path.evaluate(path.breaks[1:-1], m, "left")
        right = path.evaluate(path.breaks[1:-1], m, "right")
        np.testing.assert_allclose(left, right, atol=1e-9)
    res = time_optimal(path, Limits(velocity=[1.0, 1.0], acceleration=[1.0, 1.0]))
    t_mid = res.trajectory.breaks[res.trajectory.waypoint_index[1]]
    assert np.linalg.norm(res.trajectory.evaluate(np.array([t_mid]), 1)) > 0.05
    assert CORNER_FACTOR == pytest.approx(5 / 32)


def test_paths_through_waypoints_are_regular_and_straight_at_the_ends():
    rng = np.random.default_rng(20240611)
    wp = rng.uniform(-1, 1, (5, 4))
    path = JointPath.through(wp)
    np.testing.assert_allclose(path.evaluate(path.waypoint_s), wp, atol=1e-9)
    s = np.linspace(0, path.length, 5001)
    assert np.linalg.norm(path.evaluate(s, 1), axis=1).min() > 0.2
    np.testing.assert_allclose(path.evaluate(path.breaks[[0, -1]], 2), 0.0, atol=1e-9)
    # A trajectory's shape re-parameterised by arc length: unit speed along the path.
    arc = JointPath.from_trajectory(smooth_spline(wp, np.ones(4)))
    speed = np.linalg.norm(arc.evaluate(np.linspace(0, arc.length, 2001), 1), axis=1)
    np.testing.assert_allclose(speed[5:-5], 1.0, atol=2e-3)
    with pytest.raises(FieldError) as err:
        JointPath.through([[0.0, 1.0], [0.0, 1.0]])
    assert err.value.loc == ("waypoints",)


# ---- limits that cannot be met -------------------------------------------------------------
@pytest.mark.parametrize(("limits", "loc"), [
    (Limits(velocity=[0.0, 1.0], acceleration=[1.0, 1.0]), ("limits", "velocity")),
    (Limits(velocity=[1.0, 1.0], acceleration=[-1.0, 1.0]), ("limits", "acceleration")),
    (Limits(velocity=[1.0, 1.0, 1.0]), ("limits", "velocity")),
])
def test_limits_that_are_not_positive_name_the_field(limits, loc):
    path = smooth_polyline([[0.0, 0.0], [1.0, 1.0]], 0.0)
    with pytest.raises(FieldError) as err:
        time_optimal(path, limits)
    assert err.value.loc == loc


def test_zero_pump_flow_and_missing_accelerations_name_the_field():
    with pytest.raises(FieldError) as err:
        hydraulic_limits(PILE, pump_flow=0.0)
    assert err.value.loc == ("limits", "pump_flow")
    with pytest.raises(FieldError) as err:
        hydraulic_limits(builtin_model("glt_palletizer"), pump_flow=10.0)
    assert err.value.loc == ("limits", "pump_flow")
    path = JointPath.through([[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(FieldError) as err:
        fit_optimal(path, Limits(velocity=[1.0, 1.0], acceleration=[1.0, np.inf]))
    assert err.value.loc == ("limits", "acceleration")
    with pytest.raises(FieldError) as err:
        time_optimal(path, Limits(acceleration=[1.0, 1.0], jerk=[5.0, 5.0]), end_speed=0.1)
    assert err.value.loc == ("limits", "jerk")


def test_no_limit_at_all_is_unbounded():
    res = time_optimal(smooth_polyline([[0.0], [1.0]], 0.0), Limits())
    assert res.status is ToppStatus.UNBOUNDED and res.trajectory is None


# ---- the pile driver under its pump --------------------------------------------------------
#: Boom and stick both extend (boom up, stick out): together they ask more than the pump.
PUMP_MOVE = [[0.0, 0.1, -0.9, -0.5, 0.0, 0.0], [0.0, 0.9, -0.1, -0.5, 0.0, 0.0]]
#: The boom comes down alone: its cylinder retracts; its annulus flow stays under the pump.
RETRACT_MOVE = [[0.0, 0.9, -0.5, -0.5, 0.0, 0.0], [0.0, 0.1, -0.5, -0.5, 0.0, 0.0]]
#: A curved move of four cylinders and the slewing motor.
CURVED = [[-0.3, 0.2, -0.9, -0.6, -0.2, 0.0], [0.0, 0.6, -0.5, -0.3, 0.1, 0.0],
          [0.3, 0.9, -0.2, -0.4, 0.3, 0.0]]
ACC = np.full(6, 4.0)


def _hydraulic_data():
    """Per cylinder (mm/s, mm^2), straight from the model JSON."""
    out = {}
    for mech in PILE.extras["cylinders"]:
        for c in (mech["left"], mech["right"]) if mech["kind"] == "swing_pair" else (mech,):
            piston = math.pi * c["bore"] ** 2 / 4
            out[c["name"]] = (c["max_extension_speed"], c["max_retraction_speed"], piston,
                              piston - math.pi * c["rod"] ** 2 / 4)
    return out, PILE.extras["pump_flow"] * 1e6 / 60  # mm^3/s


def _worst(q, qd, qdd) -> dict[str, float]:
    """Largest ratio to its limit of joint accelerations, cylinder speeds and pump flow."""
    cyl, pump = _hydraulic_data()
    speeds = CylinderSet.from_model(PILE).speeds(q, qd)
    flow = np.zeros(len(q))
    ratio = 0.0
    for name, v in speeds.items():
        ext, ret, piston, annulus = cyl[name]
        ratio = max(ratio, float(np.max(np.where(v > 0, v / ext, -v / ret))))
        flow += np.where(v > 0, piston * v, -annulus * v)
    return {"cylinder": ratio, "pump": float(flow.max() / pump),
            "acceleration": float(np.max(np.abs(qdd) / ACC))}


def _ok(worst: dict[str, float], slack: float = 1e-6) -> bool:
    return all(v <= 1 + slack for v in worst.values())


@pytest.fixture(scope="module")
def curved():
    path = JointPath.through(CURVED)
    return path, time_optimal(path, Limits(acceleration=ACC), hydraulic_limits(PILE))


def test_pile_driver_keeps_cylinder_speeds_and_the_pump_flow(curved):
    _, res = curved
    assert res.success
    worst = _worst(*_dense(res.trajectory)[1:])
    assert _ok(worst)
    assert max(worst.values()) > 0.999  # and runs at a limit


def test_no_uniform_speed_up_of_the_optimum_keeps_the_limits(curved):
    """Bisection on a time factor k <= 1 of the optimal trajectory: the smallest k that
    keeps every limit is 1 (to the bisection's tolerance)."""
    _, res = curved
    lo, hi = 0.5, 1.0
    for _ in range(30):
        k = 0.5 * (lo + hi)
        if _ok(_worst(*_dense(res.trajectory.scaled(k))[1:])):
            hi = k
        else:
            lo = k
    assert hi > 0.999


def test_the_best_uniform_time_law_of_the_same_path_is_slower(curved):
    """The path traversed with the rest-to-rest quintic law s = L (10 u^3 - 15 u^4 + 6 u^5),
    u = t / T, with T found by bisection to keep every limit: T >= the optimum."""
    path, res = curved
    L = path.length

    def law_ok(T: float) -> bool:
        t = np.linspace(0, T, 4001)
        u = t / T
        s = L * (10 * u**3 - 15 * u**4 + 6 * u**5)
        sd = L * (30 * u**2 - 60 * u**3 + 30 * u**4) / T
        sdd = L * (60 * u - 180 * u**2 + 120 * u**3) / T**2
        d = path.derivatives(s, order=2)
        qd = d[1] * sd[:, None]
        return _ok(_worst(d[0], qd, d[1] * sdd[:, None] + d[2] * (sd**2)[:, None]))

    lo, hi = 0.1, 100.0
    assert law_ok(hi) and not law_ok(lo)
    for _ in range(40):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if law_ok(mid) else (mid, hi)
    assert hi >= res.duration
    assert hi > 1.05 * res.duration  # the old way is clearly slower here


@pytest.mark.parametrize(("move", "binds", "not_binding"), [
    (PUMP_MOVE, "pump", "boom extension"),
    (RETRACT_MOVE, "boom retraction", "pump"),
])
def test_binding_names_the_pump_or_the_cylinder(move, binds, not_binding):
    h = hydraulic_limits(PILE)
    res = time_optimal(JointPath.through(move), Limits(acceleration=np.full(6, 5.0)), h)
    t = np.linspace(0, res.duration, 401)
    traj = res.trajectory
    q, qd, qdd = traj.evaluate(t), traj.evaluate(t, 1), traj.evaluate(t, 2)
    ratios = limit_ratios(q, qd, qdd, None, None, np.full(6, 5.0), None, h)
    bound = binding(ratios, NAMES, h)
    middle = slice(150, 250)
    assert all(binds in b for b in bound[middle])
    assert not any(not_binding in b for b in bound)
    # The pump is at its flow exactly where it binds (recomputed from the areas).
    worst = _worst(q, qd, qdd)
    key = "pump" if binds == "pump" else "cylinder"
    assert worst[key] == pytest.approx(1.0, abs=1e-4)


# ---- jerk -------------------------------------------------------------------------------
def test_a_jerk_limit_is_kept_and_costs_little():
    rng = np.random.default_rng(91)
    wp = rng.uniform(-1.2, 1.2, (5, 6))
    v, a = rng.uniform(0.8, 2.0, 6), rng.uniform(1.5, 4.0, 6)
    j = 5 * a
    path = JointPath.through(wp)
    plain = time_optimal(path, Limits(velocity=v, acceleration=a))
    res = time_optimal(path, Limits(velocity=v, acceleration=a, jerk=j))
    traj = res.trajectory
    for m, lim in ((1, v), (2, a), (3, j)):
        assert np.all(traj.peaks(m)[0] <= lim * (1 + 1e-9))
    cont = traj.continuity()
    assert cont["position"] < 1e-9 and cont["velocity"] < 1e-9 and cont["acceleration"] < 1e-6
    np.testing.assert_allclose(traj.evaluate(traj.breaks[[0, -1]], 2), 0.0, atol=1e-9)
    assert plain.duration <= res.duration <= 1.25 * plain.duration
    # The smoothed motion stays on the path (to the grid's accuracy).
    dense = cKDTree(path.evaluate(np.linspace(0, path.length, 200001)))
    dist, _ = dense.query(traj.evaluate(np.linspace(0, traj.duration, 2000)))
    assert dist.max() < 1e-3
