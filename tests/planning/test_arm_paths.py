"""Arm paths for pile_driver (paper 000, section 4.5): reach, whole-arm clearance, joint
B-spline and cylinder lengths; the paper's printed endpoints are out of reach.

Our arm scene: the paper's obstacles are not printed and its endpoints cannot be reached
(the goal [1800, 1800, 800] mm is 2669 mm from the base, the arm reaches ~1916 mm; the start
[500, -1000, 0] is inside the hollow near the base axis), so the endpoints are the tool
positions of two in-limit configurations that differ by 0.9 rad of swing, with one sphere
(r = 200 mm) just under the straight line between them and one below the start.
"""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.cylinders import CylinderSet
from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.ik.position import REACH_TOL, reach
from kinematics.library import builtin_model
from planning.paths.arm import arm_clearance, plan_arm_path
from planning.paths.scene import Scene
from planning.status import PlanStatus

Q_START = np.array([-0.9, 0.5, -0.6, -0.4, 0.0, 0.0])
Q_GOAL = np.array([0.0, 0.5, -0.6, -0.4, 0.0, 0.0])
MARGIN = 10.0


@pytest.fixture(scope="module")
def model():
    return builtin_model("pile_driver")


@pytest.fixture(scope="module")
def endpoints(model):
    return fk(model, Q_START)[:3, 3], fk(model, Q_GOAL)[:3, 3]


@pytest.fixture(scope="module")
def scene(endpoints):
    a, b = endpoints
    mid = (a + b) / 2
    return Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]], [
        {"center": (mid + [0, 0, -230]).tolist(), "radius": 200},
        {"center": [1200, -1500, -300], "radius": 200},
    ], safety_margin=MARGIN)


@pytest.fixture(scope="module")
def planned(model, scene, endpoints):
    return plan_arm_path(model, scene, *endpoints, algorithm="auto", seed=0)


def test_the_scene_needs_a_detour(scene, endpoints, planned):
    # The straight line clears the sphere by 30 mm: the tool could pass, its links not.
    assert scene.path_clearance(np.vstack(endpoints)) < MARGIN + 60.0
    assert len(planned.tool.path) > 2


def test_every_sample_is_reached_within_limits(model, planned):
    assert planned.success, planned.message
    assert planned.status is PlanStatus.OK and planned.to_dict()["status"] == "ok"
    assert np.all(model.within_limits(planned.q))
    reached = fk(model, planned.q)[:, :3, 3]
    assert np.max(np.linalg.norm(reached - planned.points, axis=1)) < REACH_TOL
    assert np.max(np.diff(planned.s)) <= 10.0 + 1e-9  # dense: every 10 mm
    # One branch: neighbouring samples have neighbouring joints.
    assert np.max(np.abs(np.diff(planned.q, axis=0))) < 0.1


def test_the_whole_arm_keeps_clear(model, scene, planned):
    C = arm_clearance(model, scene, planned.q)
    assert C.min() >= MARGIN
    assert planned.arm_min_clearance == pytest.approx(C.min())
    # The tool path itself keeps the link radius (60 mm) on top of the margin.
    assert planned.tool.min_clearance >= MARGIN + 60.0
    # Link capsules run between consecutive frame origins.
    F = fk_frames(model, planned.q[:1])[0, :, :3, 3]
    assert C.shape == (len(planned.q), model.dof, 2) and F.shape == (model.dof + 1, 3)


def test_joint_trajectory_is_a_rest_to_rest_bspline(model, scene, planned):
    traj = planned.trajectory
    assert traj.method == "optimal"  # timed as fast as the robot's limits allow
    np.testing.assert_allclose(traj.evaluate(np.array([0.0, traj.duration])),
                               planned.q[[0, -1]], atol=1e-9)
    for derivative in (1, 2):
        np.testing.assert_allclose(traj.evaluate(np.array([0.0, traj.duration]), derivative),
                                   0.0, atol=1e-9)
    assert all(v < 1e-6 for k, v in traj.continuity().items() if k != "jerk")
    t = np.linspace(0, traj.duration, 500)
    assert np.all(model.within_limits(traj.evaluate(t)))
    assert arm_clearance(model, scene, traj.evaluate(t)).min() >= MARGIN
    assert planned.extra["trajectory_tool_deviation"] < 5.0  # mm, within the slack


def test_cylinder_lengths_stay_within_stroke(model, planned):
    cs = CylinderSet.from_model(model)
    assert set(planned.cylinders) == {"boom", "stick", "four_bar", "swing_left",
                                      "swing_right"}
    for name, L in planned.cylinders.items():
        lo, hi = cs.limits(name)
        assert L.shape == (len(planned.q),)
        assert np.all((L >= lo - 1e-9) & (L <= hi + 1e-9)), name
    assert planned.cylinders_within_stroke is True
    out = planned.to_dict()
    assert len(out["joint_path"]) == len(planned.q) and out["trajectory"]["t"][0] == 0.0
    assert set(out["cylinders"]["lengths"]) == set(planned.cylinders)


def test_papers_goal_is_unreachable(model, endpoints):
    big = Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]], [
        {"center": [1400, 700, 500], "radius": 150}])
    res = plan_arm_path(model, big, endpoints[0], [1800, 1800, 800])
    assert not res.success and res.status is PlanStatus.UNREACHABLE
    out = res.to_dict()
    assert out["status"] == "unreachable" and out["success"] is False and out["path"] == []
    assert "beyond the arm's reach" in res.message  # why, in words: the reach it has
    assert f"{reach(model):.0f} mm" in res.message
    assert 1900 < reach(model) < 1920
    res = plan_arm_path(model, big, [500, -1000, 0], endpoints[1])
    assert res.status is PlanStatus.UNREACHABLE and res.message.startswith("start ")


def test_an_arm_collision_is_named(model, endpoints):
    # A ball on the boom at the start: the tool path is clear, the arm is not.
    F = fk_frames(model, Q_START)[:, :3, 3]
    boom_mid = (F[2] + F[3]) / 2
    scene = Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]],
                         [{"center": boom_mid.tolist(), "radius": 80}])
    res = plan_arm_path(model, scene, *endpoints)
    assert not res.success and res.status is PlanStatus.COLLISION
    assert res.tool.success  # the tool path itself is clear
    assert "obstacles[0]" in res.message and "link 2" in res.message  # which, in words


def test_a_tool_path_that_cannot_be_planned_fails_with_the_planners_status(model, endpoints):
    # A wall across the whole scene between start (y < -800) and goal (y > -700).
    wall = Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]], [
        {"type": "box", "lower": [-2501, -800, -1501], "upper": [2501, -700, 2001]}])
    res = plan_arm_path(model, wall, *endpoints, algorithm="auto")
    assert res.status is PlanStatus.NO_PATH and res.tool.status is PlanStatus.NO_PATH
    assert res.to_dict()["status"] == "no_path" and len(res.q) == 0


@pytest.mark.parametrize("options, loc, words", [
    ({"link_radius": [1, 2]}, ("link_radius",), "link_radius must be one number or 6"),
    ({"duration": 0}, ("duration",), "duration must be a positive number"),
    ({"q_start": Q_GOAL}, ("q_start",), "q_start does not put the tool at start"),
    ({"keep_out_radius": -1.0}, ("keep_out_radius",),
     "keep_out_radius must be a positive number"),
])
def test_arm_inputs_are_validated(model, scene, endpoints, options, loc, words):
    with pytest.raises(FieldError) as err:
        plan_arm_path(model, scene, *endpoints, **options)
    assert err.value.loc == loc and words in err.value.message


def test_an_endpoint_too_close_for_the_links_names_it(model, endpoints):
    # Clear of the sphere for the tool point, not for the 60 mm links around it.
    scene = Scene.create([[-2500, -2500, -1500], [2500, 2500, 2000]], [
        {"center": (endpoints[1] + [0, 0, 250]).tolist(), "radius": 200}])
    with pytest.raises(FieldError) as err:
        plan_arm_path(model, scene, *endpoints)
    assert err.value.loc == ("goal",) and "obstacles[0]" in err.value.message
