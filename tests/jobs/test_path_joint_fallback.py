"""The ``path`` job with a robot falls back to joint-space motion planning when the arm cannot
follow the tool path: random moves of pile_driver and glt_palletizer (tool points of random
in-limit configurations, no obstacles) that the tool path alone fails on, an arm that would hit
an obstacle, a goal given as joint values, a stored scene's own objects.

Every returned motion is checked here on its own terms: the tool samples are FK of the joint
samples, the joints stay within their limits, the ends reach the asked points, and the joint
path's straight segments, stepped finer than the planner checks them, are collision-free by
``planning.collision.collides(..., exact=True)`` in a scene built here.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from app.jobs.path_kinds import PathParams, run_path, scene_params
from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.ik.position import REACH_TOL
from kinematics.library import builtin_model
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.paths.arm import arm_clearance
from planning.paths.scene import Scene

pytestmark = pytest.mark.usefixtures("motion_kernels")

OPEN = {"bounds": [[-5000, -5000, -5000], [5000, 5000, 5000]]}
#: Joint step (rad) of the independent check: half the planner's default resolution.
CHECK_STEP = 0.005


def _params(robot: str, start, goal, **arm) -> PathParams:
    body = {"scene": OPEN, "robot": robot, "algorithm": "auto"}
    if start is not None:
        body["start"] = np.asarray(start).tolist()
    if goal is not None:
        body["goal"] = np.asarray(goal).tolist()
    if arm:
        body["arm"] = arm
    return PathParams.model_validate(body)


def _run(params: PathParams):
    return run_path(params, lambda f, m: None)


def _dense(path: np.ndarray, step: float) -> np.ndarray:
    """States along the straight segments of ``path (K, dof)`` at most ``step`` apart (rad;
    these arms' joints are all revolute)."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.max(np.abs(b - a)) / step)))
        out.append(a + np.arange(1, n + 1)[:, None] / n * (b - a))
    return np.vstack(out)


def _check_motion(model, res, start, goal, scene=None, margin=0.0):
    """The result's own promises, checked independently (module docstring)."""
    assert res.success, res.message
    q = np.asarray(res.joint_path)
    tool = np.asarray(res.tool_samples)
    assert np.all(model.within_limits(q))
    # Joint space: the tool samples are FK of the joints; tool space: the IK reached them.
    np.testing.assert_allclose(fk(model, q)[:, :3, 3], tool,
                               atol=1e-6 if res.planner == "joint_space" else REACH_TOL)
    assert np.linalg.norm(tool[0] - start) <= REACH_TOL
    assert np.linalg.norm(tool[-1] - goal) <= REACH_TOL
    assert np.max(np.linalg.norm(np.diff(tool, axis=0), axis=1)) <= 10.0 + 2 * REACH_TOL
    traj = res.trajectory
    np.testing.assert_allclose(traj.q[0], q[0], atol=1e-9)
    np.testing.assert_allclose(traj.q[-1], q[-1], atol=1e-9)
    assert np.all(model.within_limits(np.asarray(traj.q), tol=1e-6))
    if res.planner == "joint_space":
        waypoints = np.asarray(traj.waypoints)
        np.testing.assert_array_equal(waypoints[0], q[0])
        np.testing.assert_array_equal(waypoints[-1], q[-1])
        cm = RobotCollisionModel.from_model(model)
        states = _dense(waypoints, CHECK_STEP)
        assert not np.any(collides(cm, states, scene, exact=True, margin=margin))
        assert not np.any(collides(cm, np.asarray(traj.q), scene, exact=True, margin=margin))


@pytest.mark.slow
@pytest.mark.parametrize("robot", ["pile_driver", "glt_palletizer"])
def test_random_moves_in_open_space_all_succeed(robot):
    """Ten moves between the tool points of random in-limit configurations: the tool path
    alone fails on some (it leaves the reach, the IK cannot follow it); with the joint-space
    fallback every one succeeds."""
    model = builtin_model(robot)
    rng = np.random.default_rng(20_240_611)
    planners = []
    tool_only_failures = 0
    for _ in range(10):
        Q = rng.uniform(model.lower, model.upper, size=(2, model.dof))
        start, goal = fk(model, Q)[:, :3, 3]
        tool_only = _run(_params(robot, start, goal, joint_space="never"))
        tool_only_failures += not tool_only.success
        res = _run(_params(robot, start, goal))
        _check_motion(model, res, start, goal)
        planners.append(res.planner)
        if res.planner == "joint_space":
            assert res.status == "ok" and tool_only.message in res.message
            assert res.algorithm.startswith("rrt")
        else:  # the tool path was followed: the same answer as without the fallback
            assert tool_only.success and res.joint_path == tool_only.joint_path
    assert tool_only_failures >= 1
    assert planners.count("joint_space") == tool_only_failures


def test_an_arm_that_would_hit_an_obstacle_moves_round_it_in_joint_space():
    """A ball where the stick passes half-way through a swing: the tool path is clear, the
    arm following it is not; the joint-space motion keeps the margin."""
    model = builtin_model("pile_driver")
    qa = np.array([-0.9, 0.5, -0.6, -0.4, 0.0, 0.0])
    qb = np.array([0.0, 0.5, -0.6, -0.4, 0.0, 0.0])
    F = fk_frames(model, (qa + qb) / 2)[:, :3, 3]
    ball = (F[2] + F[3]) / 2
    scene = {"bounds": [[-2500, -2500, -1500], [2500, 2500, 2000]],
             "obstacles": [{"center": ball.tolist(), "radius": 120}], "safety_margin": 10}
    start, goal = fk(model, np.stack([qa, qb]))[:, :3, 3]
    body = {"scene": scene, "start": start.tolist(), "goal": goal.tolist(),
            "robot": "pile_driver"}
    tool_only = _run(PathParams.model_validate({**body, "arm": {"joint_space": "never"}}))
    assert tool_only.status == "collision" and "obstacles[0]" in tool_only.message
    res = _run(PathParams.model_validate(body))
    assert res.planner == "joint_space" and "the arm hits an obstacle" in res.message
    T = np.eye(4)
    T[:3, 3] = ball
    here = CollisionScene.from_dicts([{"type": "sphere", "radius": 120, "pose": T.tolist()}])
    _check_motion(model, res, start, goal, here, margin=10.0)
    # The same clearance by the tool-path planner's own exact capsule distances.
    C = arm_clearance(model, Scene.from_dict(scene), np.asarray(res.joint_path))
    assert C.min() >= 10.0 and res.arm_min_clearance >= 10.0 - 1e-6
    assert res.cylinders.within_stroke is True


def test_a_goal_configuration_is_reached_in_joint_space():
    model = builtin_model("glt_palletizer")
    q0 = np.array([0.3, 0.2, -0.4, 0.0, 0.6, 0.0])
    q1 = np.array([-2.4, 0.6, -0.9, 1.0, -0.8, 2.0])
    start = fk(model, q0)[:3, 3]
    res = _run(_params("glt_palletizer", start, None, q_start=q0.tolist(),
                       q_goal=q1.tolist()))
    assert res.planner == "joint_space"
    np.testing.assert_array_equal(res.joint_path[0], q0)
    np.testing.assert_array_equal(res.joint_path[-1], q1)  # the very configuration asked
    _check_motion(model, res, start, fk(model, q1)[:3, 3])
    # The start may be given as joint values alone too.
    res = _run(_params("glt_palletizer", None, None, q_start=q0.tolist(), q_goal=q1.tolist(),
                       joint_space="always"))
    assert res.success and res.joint_path[0] == q0.tolist()


@pytest.mark.parametrize("body, loc", [
    ({"start": [0, 0, 0]}, ("goal",)),
    ({"goal": [0, 0, 0], "arm": {"q_goal": [0] * 6}}, ("start",)),
    ({"start": [0, 0, 0], "arm": {"q_goal": [0] * 6}, "robot": None}, ("robot",)),
    ({"start": [0, 0, 0], "goal": [1, 1, 1], "arm": {"joint_space": "sometimes"}},
     ("arm", "joint_space")),
])
def test_missing_endpoints_and_bad_options_name_the_field(body, loc):
    with pytest.raises(ValidationError) as err:
        PathParams.model_validate({"scene": OPEN, "robot": "glt_palletizer", **body})
    assert err.value.errors()[0]["loc"] == loc


def test_inconsistent_configurations_name_the_field():
    model = builtin_model("glt_palletizer")
    q = [0.3, 0.2, -0.4, 0.0, 0.6, 0.0]
    p = fk(model, np.array(q))[:3, 3]
    with pytest.raises(FieldError) as err:
        _run(_params("glt_palletizer", p, p + 100.0, q_goal=q))
    assert err.value.loc == ("q_goal",) and "does not put the tool at goal" in err.value.message
    with pytest.raises(FieldError) as err:
        _run(_params("glt_palletizer", p, None, q_goal=q, joint_space="never"))
    assert err.value.loc == ("joint_space",)
    with pytest.raises(FieldError) as err:
        _run(_params("glt_palletizer", p, None, q_goal=[9.0] + q[1:]))
    assert err.value.loc == ("q_goal",) and "waist" in err.value.message


def _bar_mesh(center, size) -> dict:
    """A closed box mesh (12 triangles) of ``size`` at ``center``, as inline vertices."""
    c, h = np.asarray(center, dtype=float), np.asarray(size, dtype=float) / 2
    V = c + h * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    F = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
         [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return {"type": "mesh", "id": "bar", "vertices": V.tolist(), "faces": F}


@pytest.mark.slow
def test_a_stored_scenes_own_objects_are_what_the_joint_space_motion_avoids():
    """A stored scene becomes conservative obstacles for the tool path and its own objects
    (a mesh here) for the joint-space motion, recorded in the params; a plain path (no robot)
    does not keep them."""
    model = builtin_model("pile_driver")
    qa = np.array([-0.9, 0.5, -0.6, -0.4, 0.0, 0.0])
    qb = np.array([0.0, 0.5, -0.6, -0.4, 0.0, 0.0])
    F = fk_frames(model, (qa + qb) / 2)[:, :3, 3]
    stored = CollisionScene.from_dicts([_bar_mesh((F[2] + F[3]) / 2, [200, 200, 200])])
    start, goal = fk(model, np.stack([qa, qb]))[:, :3, 3]
    scene = scene_params(stored, {"id": "site"}, [start.tolist(), goal.tolist()])
    assert scene["obstacles"][0]["type"] == "box" and scene["objects"][0]["type"] == "mesh"
    body = {"scene": scene, "start": start.tolist(), "goal": goal.tolist(),
            "robot": "pile_driver", "arm": {"joint_space": "always"}}
    params = PathParams.model_validate(body)
    res = _run(params)
    _check_motion(model, res, start, goal, stored)
    assert params.model_dump(mode="json")["scene"]["objects"][0]["faces"][0] == [0, 1, 3]
    plain = PathParams.model_validate({k: v for k, v in body.items()
                                       if k not in ("robot", "arm")})
    assert plain.scene.objects is None
    with pytest.raises(ValidationError):
        PathParams.model_validate({**body, "scene": {k: v for k, v in scene.items()
                                                     if k != "id"}})


@pytest.mark.slow
def test_a_joint_space_path_job_through_the_api(jobs_client):
    """A stored scene with a mesh, a goal given as joint values: the job records the mesh
    inline and publishes the joint-space motion with its planner named."""
    from .conftest import wait_for

    model = builtin_model("pile_driver")
    qa = [-0.9, 0.5, -0.6, -0.4, 0.0, 0.0]
    qb = [0.0, 0.5, -0.6, -0.4, 0.0, 0.0]
    F = fk_frames(model, (np.array(qa) + np.array(qb)) / 2)[:, :3, 3]
    stored = {"id": "site", "objects": [_bar_mesh((F[2] + F[3]) / 2, [200, 200, 200])]}
    assert jobs_client.post("/scenes", json=stored).status_code == 201
    r = jobs_client.post("/jobs", json={"kind": "path", "params": {
        "scene": "site", "robot": "pile_driver", "arm": {"q_start": qa, "q_goal": qb}}})
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["params"]["scene"]["objects"][0]["vertices"] == stored["objects"][0]["vertices"]
    done = wait_for(jobs_client, job["id"], timeout=120)
    assert done["status"] == "succeeded", done
    out = jobs_client.get(f"/jobs/{job['id']}/result").json()
    assert out["planner"] == "joint_space" and out["success"] and out["robot"] == "pile_driver"
    assert out["joint_path"][0] == qa and out["joint_path"][-1] == qb
    here = CollisionScene.from_dicts(stored["objects"])
    cm = RobotCollisionModel.from_model(model)
    assert not np.any(collides(cm, _dense(np.asarray(out["trajectory"]["waypoints"]),
                                          CHECK_STEP), here, exact=True))
