"""``planning.motion.request``: a motion body read against a robot, every mistake a
``FieldError`` naming the field; a batch's problems sharing its settings."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.motion.request import (
    DEFAULT_TIME_LIMIT_S,
    MAX_PROBLEMS,
    is_batch,
    parse_motion_problems,
    parse_motion_request,
)

pytestmark = pytest.mark.usefixtures("motion_kernels")

MODEL = builtin_model("glt_palletizer")  # 6 revolute joints
Q0 = [0.0] * 6
Q1 = [0.5, 0.2, -0.2, 0.0, 0.4, 0.0]


def _loc(body, **kw) -> tuple:
    with pytest.raises(FieldError) as err:
        parse_motion_problems(body, MODEL, **kw)
    return err.value.loc


def test_defaults_are_filled_in():
    req = parse_motion_request({"start": Q0, "goal": {"q": Q1}}, MODEL)
    assert req.start.tolist() == Q0 and req.goal.tolist() == Q1 and req.goal_pose is None
    assert (req.planner, req.time_limit, req.seed, req.resolution) == (
        "auto", DEFAULT_TIME_LIMIT_S, 0, 0.01)
    assert req.simplify and req.self_collision and req.trajectory and req.margin == 0.0
    assert req.scene is None
    # A lower cap on the time limit lowers its default too.
    assert parse_motion_request({"start": Q0, "goal": {"q": Q1}}, MODEL,
                                max_time_limit=2.0).time_limit == 2.0


def test_a_goal_pose_is_projected_onto_the_nearest_rigid_pose():
    T = fk(MODEL, np.array(Q1))
    printed = np.round(T, 4)  # four decimals, as papers print them: not exactly rigid
    req = parse_motion_request({"start": Q0, "goal": {"pose": printed.tolist()}}, MODEL)
    assert req.goal is None
    R = req.goal_pose[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(req.goal_pose, T, atol=1e-3)


@pytest.mark.parametrize("body, loc", [
    ({"start": Q0[:5], "goal": {"q": Q1}}, ("start",)),
    ({"start": [*Q0[:5], float("nan")], "goal": {"q": Q1}}, ("start", 5)),
    ({"start": [*Q0[:5], True], "goal": {"q": Q1}}, ("start", 5)),
    ({"start": "000000", "goal": {"q": Q1}}, ("start",)),
    ({"goal": {"q": Q1}}, ("start",)),
    ({"start": Q0}, ("goal",)),
    ({"start": Q0, "goal": Q1}, ("goal",)),
    ({"start": Q0, "goal": {"q": Q1, "pose": np.eye(4).tolist()}}, ("goal",)),
    ({"start": Q0, "goal": {"joints": Q1}}, ("goal", "joints")),
    ({"start": Q0, "goal": {"q": Q1[:2]}}, ("goal", "q")),
    ({"start": Q0, "goal": {"pose": np.eye(3).tolist()}}, ("goal", "pose")),
    ({"start": Q0, "goal": {"pose": (2 * np.eye(4)).tolist()}}, ("goal", "pose")),
    ({"start": Q0, "goal": {"pose": [[1, 0, 0, float("inf")], [0, 1, 0, 0], [0, 0, 1, 0],
                                     [0, 0, 0, 1]]}}, ("goal", "pose")),
    ({"start": Q0, "goal": {"q": Q1}, "planner": "prm"}, ("planner",)),
    ({"start": Q0, "goal": {"q": Q1}, "time_limit": 0}, ("time_limit",)),
    ({"start": Q0, "goal": {"q": Q1}, "time_limit": 61}, ("time_limit",)),
    ({"start": Q0, "goal": {"q": Q1}, "resolution": 0.0}, ("resolution",)),
    ({"start": Q0, "goal": {"q": Q1}, "resolution": 0.51}, ("resolution",)),
    # Finer than 1e-4 rad: work without bound (1e-12 took 10 min; 1e-308 overflowed).
    ({"start": Q0, "goal": {"q": Q1}, "resolution": 9e-5}, ("resolution",)),
    ({"start": Q0, "goal": {"q": Q1}, "resolution": 1e-12}, ("resolution",)),
    ({"start": Q0, "goal": {"q": Q1}, "resolution": 5e-324}, ("resolution",)),
    ({"start": Q0, "goal": {"q": Q1}, "seed": -1}, ("seed",)),
    ({"start": Q0, "goal": {"q": Q1}, "seed": 1.5}, ("seed",)),
    ({"start": Q0, "goal": {"q": Q1}, "margin": -1}, ("margin",)),
    ({"start": Q0, "goal": {"q": Q1}, "simplify": "yes"}, ("simplify",)),
    ({"start": Q0, "goal": {"q": Q1}, "scene": 3}, ("scene",)),
    ({"start": Q0, "goal": {"q": Q1}, "speed": 1}, ("speed",)),
])
def test_each_mistake_names_its_field(body, loc):
    assert _loc(body) == loc


def test_a_batch_shares_the_settings_and_overrides_seed_and_time_limit():
    body = {"problems": [{"start": Q0, "goal": {"q": Q1}},
                         {"start": Q1, "goal": {"q": Q0}, "seed": 9, "time_limit": 1.5}],
            "seed": 4, "time_limit": 3.0, "planner": "rrt_star", "margin": 20,
            "scene": "cell", "robot": "ignored"}
    assert is_batch(body)
    first, second = parse_motion_problems(body, MODEL, ignore=("robot",))
    assert (first.seed, first.time_limit) == (4, 3.0)
    assert (second.seed, second.time_limit) == (9, 1.5)
    for req in (first, second):
        assert (req.planner, req.margin, req.scene) == ("rrt_star", 20.0, "cell")
    assert second.start.tolist() == Q1


@pytest.mark.parametrize("body, loc", [
    ({"problems": []}, ("problems",)),
    ({"problems": {"start": Q0}}, ("problems",)),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}}] * (MAX_PROBLEMS + 1)}, ("problems",)),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}}, {"start": Q0}]},
     ("problems", 1, "goal")),
    ({"problems": [{"start": Q0, "goal": {"q": Q1[:3]}}]}, ("problems", 0, "goal", "q")),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}, "planner": "auto"}]},
     ("problems", 0, "planner")),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}, "seed": -2}]}, ("problems", 0, "seed")),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}}], "start": Q0}, ("start",)),
    ({"problems": [{"start": Q0, "goal": {"q": Q1}}], "time_limit": 100}, ("time_limit",)),
])
def test_batch_mistakes_name_the_problem(body, loc):
    assert _loc(body) == loc


def test_the_robot_field_must_be_ignored_explicitly():
    body = {"robot": "glt_palletizer", "start": Q0, "goal": {"q": Q1}}
    assert _loc(body) == ("robot",)
    assert parse_motion_request(body, MODEL, ignore=("robot",)).start.tolist() == Q0


def test_a_read_request_plans_without_being_checked_again(monkeypatch):
    """The request is checked once, where it is read: ``plan`` hands its values to the
    planner (``plan_checked``) and never runs ``plan_motion``'s checks, and gives the answer
    ``plan_motion`` gives for the same problem."""
    from planning.collision import RobotCollisionModel
    from planning.motion import planner

    req = parse_motion_request({"start": Q0, "goal": {"q": Q1}, "seed": 3, "time_limit": 5,
                                "trajectory": False}, MODEL)
    checker = req.checker(RobotCollisionModel.from_model(MODEL))
    direct = planner.plan_motion(checker, Q0, Q1, seed=3, time_limit=5, trajectory=False)

    def refuse(*args, **kwargs):
        raise AssertionError("plan_motion's checks ran again")

    monkeypatch.setattr(planner, "plan_motion", refuse)
    via_request = req.plan(checker)
    assert via_request.status == direct.status == "ok"
    np.testing.assert_array_equal(via_request.path, direct.path)
