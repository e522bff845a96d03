"""Jerk-limited point-to-point moves (planning.trajectories.p2p): the textbook S-curve
durations in closed form, synchronised arrival, end velocities, and the hydraulics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kinematics.cylinders import CylinderSet
from kinematics.errors import FieldError
from kinematics.library import builtin_model
from planning.trajectories.hydraulic import hydraulic_limits
from planning.trajectories.p2p import jerk_limited, velocity_change
from planning.trajectories.trajectory import Limits


def _within(traj, V, A, J, rel=1e-9) -> bool:
    return all(np.all(traj.peaks(m)[0] <= np.asarray(lim) * (1 + rel) + 1e-12)
               for m, lim in ((1, V), (2, A), (3, J)))


@pytest.mark.parametrize(("d", "V", "A", "J", "T"), [
    # Room to reach V and A: T = d/V + V/A + A/J.
    (10.0, 2.0, 1.0, 2.0, 10.0 / 2.0 + 2.0 / 1.0 + 1.0 / 2.0),
    # A reached, V not: vp = A (sqrt(1/4 A^2/J^2 + d/A) ... ) -- here with A^2/J = 0.5,
    # d = 2: vp solves vp (vp/A + A/J) = d, vp = 1.186..., T = 2 (vp/A + A/J).
    (2.0, 3.0, 1.0, 2.0, 2.0 * ((-0.5 + math.sqrt(0.25 + 8.0)) / 2.0 + 0.5)),
    # Neither: a jerk triangle, d = 2 J tj^3, T = 4 tj.
    (0.02, 3.0, 5.0, 2.0, 4.0 * (0.02 / 4.0) ** (1 / 3)),
])
def test_one_joint_takes_the_textbook_s_curve_time(d, V, A, J, T):
    move = jerk_limited([0.0], [d], Limits(velocity=[V], acceleration=[A], jerk=[J]))
    assert move.duration == pytest.approx(T, rel=1e-9)
    traj = move.trajectory
    assert _within(traj, [V], [A], [J])
    np.testing.assert_allclose(traj.evaluate(traj.breaks[[-1]]), [[d]], atol=1e-12)
    for m in (1, 2):
        np.testing.assert_allclose(traj.evaluate(traj.breaks[[0, -1]], m), 0.0, atol=1e-9)
    cont = traj.continuity()
    assert cont["position"] < 1e-12 and cont["velocity"] < 1e-12 and cont["acceleration"] < 1e-9


def test_velocity_change_is_the_trapezoid_or_the_triangle():
    assert velocity_change(2.0, 1.0, 1.0) == [(1.0, 1.0), (1.0, 0.0), (1.0, -1.0)]
    tj = math.sqrt(0.3 / 2.0)  # |dv| below A^2 / J = 0.5: A is never reached
    assert velocity_change(-0.3, 1.0, 2.0) == [(tj, -2.0), (tj, 2.0)]


def test_joints_arrive_together_each_within_its_limits():
    rng = np.random.default_rng(4417)
    start, end = rng.uniform(-2, 2, 6), rng.uniform(-2, 2, 6)
    end[3] = start[3]  # one joint stays
    V, A, J = rng.uniform(0.5, 2, 6), rng.uniform(0.5, 4, 6), rng.uniform(1, 20, 6)
    move = jerk_limited(start, end, Limits(velocity=V, acceleration=A, jerk=J))
    traj = move.trajectory
    assert move.duration == pytest.approx(move.joint_durations.max())
    assert move.joint_durations[3] == 0 and move.limiting_joint == int(np.argmax(
        move.joint_durations))
    np.testing.assert_allclose(traj.evaluate(traj.breaks[[-1]])[0], end, atol=1e-12)
    assert _within(traj, V, A, J)
    # Every moving joint still moves until near the end: the faster ones were slowed.
    late = traj.evaluate(np.array([0.9 * traj.duration]), 1)[0]
    moving = np.abs(end - start) > 0
    assert np.all(np.abs(late[moving]) > 0) and late[3] == 0


def test_an_end_velocity_is_reached_with_zero_acceleration():
    V, A, J = np.array([1.0, 2.0]), np.array([2.0, 1.0]), np.array([10.0, 5.0])
    vf = np.array([0.5, -0.2])
    move = jerk_limited([0.0, 1.0], [3.0, -1.0], Limits(velocity=V, acceleration=A, jerk=J),
                        end_velocity=vf)
    traj = move.trajectory
    T = traj.duration
    np.testing.assert_allclose(traj.evaluate(np.array([T]))[0], [3.0, -1.0], atol=1e-9)
    np.testing.assert_allclose(traj.evaluate(np.array([T]), 1)[0], vf, atol=1e-9)
    np.testing.assert_allclose(traj.evaluate(np.array([T]), 2)[0], 0.0, atol=1e-9)
    assert _within(traj, V, A, J)


@pytest.mark.parametrize(("limits", "end_velocity", "loc"), [
    (Limits(velocity=[1.0], acceleration=[1.0]), None, ("limits", "jerk")),
    (Limits(velocity=[1.0], acceleration=[0.0], jerk=[1.0]), None, ("limits", "acceleration")),
    (Limits(velocity=[1.0], acceleration=[1.0], jerk=[1.0]), [2.0], ("end_velocity", 0)),
    (Limits(velocity=[1.0], acceleration=[1.0], jerk=[1.0]), [-0.5], ("end_velocity", 0)),
])
def test_bad_limits_and_end_velocities_name_the_field(limits, end_velocity, loc):
    with pytest.raises(FieldError) as err:
        jerk_limited([0.0], [1.0], limits, end_velocity)
    assert err.value.loc == loc


def test_pile_driver_move_keeps_its_cylinders_and_pump():
    model = builtin_model("pile_driver")
    h = hydraulic_limits(model)
    start = np.array([0.0, 0.1, -0.9, -0.5, -0.2, 0.0])
    end = np.array([0.5, 0.9, -0.1, -0.3, 0.2, 0.0])
    lim = Limits(velocity=[1.0, np.inf, np.inf, np.inf, np.inf, 1.0],
                 acceleration=np.full(6, 2.0), jerk=np.full(6, 10.0))
    traj = jerk_limited(start, end, lim, hydraulics=h).trajectory
    t = np.linspace(0, traj.duration, 4001)
    q, qd = traj.evaluate(t), traj.evaluate(t, 1)
    speeds = CylinderSet.from_model(model).speeds(q, qd)
    flow = np.zeros(len(t))
    for mech in model.extras["cylinders"]:
        for c in (mech["left"], mech["right"]) if mech["kind"] == "swing_pair" else (mech,):
            v = speeds[c["name"]]
            assert v.max() <= c["max_extension_speed"] * (1 + 1e-6)
            assert -v.min() <= c["max_retraction_speed"] * (1 + 1e-6)
            piston = math.pi * c["bore"] ** 2 / 4
            flow += np.where(v > 0, piston * v, -(piston - math.pi * c["rod"] ** 2 / 4) * v)
    assert flow.max() <= model.extras["pump_flow"] * 1e6 / 60 * (1 + 1e-6)
    assert flow.max() >= 0.999 * model.extras["pump_flow"] * 1e6 / 60  # the pump binds
