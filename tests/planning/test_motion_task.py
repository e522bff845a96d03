"""Tasks of the motion planner (planning.motion.task): moves, lines and arcs planned in turn,
answered as one joint path, one trajectory and a status per step.

The arm is a UR5-like standard D-H model written here; the tool poses of the answered states
are recomputed with a D-H product written here too (not the kinematics package's FK)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from ur5_like import off_line, ur5_fk, ur5_model

from kinematics.errors import FieldError
from planning.collision import CollisionScene, RobotCollisionModel
from planning.motion import MotionChecker
from planning.motion.task import (
    MAX_TASK_STEPS,
    STEP_TYPES,
    StepType,
    TaskRequest,
    parse_task,
    plan_task,
)

pytestmark = pytest.mark.usefixtures("motion_kernels")

PI = math.pi
Q0 = np.array([0.0, -1.2, 1.5, -1.9, -1.57, 0.3])
Q1 = np.array([0.6, -1.0, 1.3, -1.9, -1.57, 0.3])
#: The line: 150 mm straight down from the tool's position at Q1.
DROP = np.array([0.0, 0.0, -150.0])
TOL_P = 0.1


@pytest.fixture(scope="module")
def ur5():
    model = ur5_model()
    cm = RobotCollisionModel.from_model(model, link_radius=40.0)
    return model, cm


def move_line_move() -> list[dict]:
    p1 = ur5_fk(Q1)[0, :3, 3]
    return [{"type": "move", "goal": {"q": Q1.tolist()}},
            {"type": "line", "target": (p1 + DROP).tolist(), "orientation": "hold"},
            {"type": "move", "goal": {"q": Q0.tolist()}}]


def test_a_move_a_line_and_a_move_make_one_continuous_timed_path(ur5):
    model, cm = ur5
    res = plan_task(MotionChecker(cm), Q0, move_line_move(), time_limit=5.0)
    assert res.status == "ok" and res.message == "ok", res.message
    path = res.path
    assert path.dtype == np.float64 and path.shape[1] == 6
    np.testing.assert_array_equal(path[0], Q0)
    np.testing.assert_allclose(path[-1], Q0, atol=1e-12)
    # The steps' states follow one another: each step starts where the one before ended.
    ranges = [(s.first, s.last) for s in res.steps]
    assert [s.type for s in res.steps] == ["move", "line", "move"]
    assert [s.status for s in res.steps] == ["ok"] * 3
    assert ranges[0][0] == 0 and ranges[-1][1] == len(path) - 1
    assert all(a[1] == b[0] and a[0] < a[1] for a, b in zip(ranges, ranges[1:]))
    np.testing.assert_allclose(path[ranges[0][1]], Q1, atol=1e-12)
    # The line's states lie on the line (FK recomputed here), from Q1's tool position to
    # 150 mm below it, the orientation held, the joints moving by less than the default
    # jump threshold between two states.
    first, last = ranges[1]
    line = path[first:last + 1]
    T = ur5_fk(line)
    p0 = ur5_fk(Q1)[0, :3, 3]
    dist, t = off_line(T[:, :3, 3], p0, p0 + DROP)
    assert dist.max() <= TOL_P
    assert t[0] == pytest.approx(0.0, abs=1e-9) and t[-1] == pytest.approx(1.0, abs=1e-3)
    assert np.all(np.diff(t) > 0)
    assert len(line) == 31   # 150 mm at 5 mm steps
    R0 = ur5_fk(Q1)[0, :3, :3]
    assert np.abs(T[:, :3, :3] - R0).max() < 2e-3
    assert np.abs(np.diff(line, axis=0)).max() <= 0.3
    assert res.steps[1].fraction == 1.0 and res.steps[0].fraction is None
    assert res.steps[1].planner == "line" and res.steps[0].planner == "rrt_connect"
    # One trajectory over the whole path, from the start back to it, continuous.
    traj = res.trajectory
    assert traj is not None and traj.duration > 0
    ts = np.linspace(0.0, traj.duration, 4001)
    Q = traj.evaluate(ts)
    np.testing.assert_allclose(Q[0], Q0, atol=1e-9)
    np.testing.assert_allclose(Q[-1], Q0, atol=1e-9)
    vmax = np.asarray(model.velocity_limits)
    assert np.all(np.abs(np.diff(Q, axis=0)) <= vmax * (ts[1] - ts[0]) * 1.01 + 1e-9)
    # Corners blended (no stop at the line's states), and the line kept: every state of the
    # line is passed within 0.01 rad, and between the line's ends the tool stays within 1 mm
    # of the line.
    assert "trajectory" not in res.stats
    near = np.abs(Q[:, None, :] - line[None]).max(axis=2)
    assert near.min(axis=0).max() < 0.01
    i0, i1 = near[:, 0].argmin(), near[:, -1].argmin()
    assert i1 - i0 > 200
    d_traj, _ = off_line(ur5_fk(Q[i0:i1 + 1])[:, :3, 3], p0, p0 + DROP)
    assert d_traj.max() < 1.0
    assert res.to_dict()["steps"][1]["states"] == [first, last]


def test_a_line_into_an_obstacle_stops_the_task_at_that_step(ur5):
    model, cm = ur5
    p1 = ur5_fk(Q1)[0, :3, 3]
    # A box 100 mm below the tool at Q1: the line down runs into it.
    pose = np.eye(4)
    pose[:3, 3] = p1 + [0.0, 0.0, -100.0 - 60.0]
    scene = CollisionScene.from_request({"objects": [
        {"type": "box", "id": "block", "size": [300.0, 300.0, 40.0], "pose": pose.tolist()}]})
    steps = move_line_move()
    alone = plan_task(MotionChecker(cm, scene), Q0, steps[:1], time_limit=5.0)
    res = plan_task(MotionChecker(cm, scene), Q0, steps, time_limit=5.0)
    assert res.status == "collision"
    assert res.message.startswith("step 1 (line): ")
    assert [s.status for s in res.steps] == ["ok", "collision"]   # the last move not planned
    assert res.stats["steps_planned"] == 2 and res.stats["steps"] == 3
    line = res.steps[1]
    assert 0.0 < line.fraction < 1.0
    assert any("block" in pair for pair in line.pairs) and res.pairs == line.pairs
    # The earlier step's path is answered as planned alone, then the line up to the box.
    a, b = res.steps[0].first, res.steps[0].last
    np.testing.assert_array_equal(res.path[a:b + 1], alone.path)
    assert line.first == b and line.last == len(res.path) - 1
    reached = ur5_fk(res.path[line.last])[0, :3, 3]
    assert 0.0 < p1[2] - reached[2] < 100.0
    assert (p1[2] - reached[2]) / 150.0 == pytest.approx(line.fraction, abs=TOL_P / 150)
    assert res.trajectory is None and res.goal is None and res.min_clearance is None
    out = res.to_dict(["j1", "j2", "j3", "j4", "j5", "j6"])
    assert out["status"] == "collision" and out["trajectory"] is None
    assert out["steps"][1]["fraction"] == line.fraction and len(out["steps"]) == 2


def test_an_arc_step_follows_its_circle(ur5):
    model, cm = ur5
    p1 = ur5_fk(Q1)[0, :3, 3]
    centre = p1 + [0.0, -60.0, 0.0]
    res = plan_task(MotionChecker(cm), Q1, [
        {"type": "arc", "centre": centre.tolist(), "axis": [0, 0, 1], "angle": 1.0,
         "orientation": "hold"}], time_limit=5.0)
    assert res.status == "ok", res.message
    P = ur5_fk(res.path)[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(P[:, :2] - centre[:2], axis=1), 60.0, atol=TOL_P)
    np.testing.assert_allclose(P[:, 2], p1[2], atol=TOL_P)
    assert res.steps[0].planner == "arc" and res.steps[0].fraction == 1.0


def test_the_task_time_limit_bounds_every_step(ur5):
    model, cm = ur5
    steps = [{"type": "line", "target": (ur5_fk(Q0)[0, :3, 3] + DROP).tolist(),
              "max_step": 0.5}] + move_line_move()
    res = plan_task(MotionChecker(cm), Q0, steps, time_limit=0.005)
    assert res.status == "timeout"
    assert res.steps[-1].status == "timeout" and len(res.steps) <= 2


def test_errors_name_the_step_and_its_field(ur5):
    model, _ = ur5
    body = {"start": Q0.tolist(), "steps": move_line_move()}

    def loc_of(steps: list, **extra) -> tuple:
        with pytest.raises(FieldError) as err:
            parse_task({**body, "steps": steps, **extra}, model)
        return err.value.loc

    good = move_line_move()
    assert loc_of(good[:2] + [{"type": "line", "target": [1, 2]}]) == ("steps", 2, "target")
    assert loc_of(good[:2] + [{"type": "line"}]) == ("steps", 2, "target")
    assert loc_of([good[0], {**good[1], "max_step": -1}]) == ("steps", 1, "max_step")
    assert loc_of([good[0], {**good[1], "orientation": "rotate"}]) == (
        "steps", 1, "orientation")
    assert loc_of([good[0], {**good[1], "speed": 3}]) == ("steps", 1, "speed")
    assert loc_of([{"type": "move", "goal": {"q": [0.0] * 5}}]) == ("steps", 0, "goal", "q")
    assert loc_of([good[0], {"type": "move", "goal": {"q": Q0.tolist()}, "planner": "x"}]) \
        == ("steps", 1, "planner")
    assert loc_of([{"type": "teleport"}]) == ("steps", 0, "type")
    assert loc_of(["move"]) == ("steps", 0)
    assert loc_of([good[0]] * (MAX_TASK_STEPS + 1)) == ("steps",)
    assert loc_of([{"type": "arc", "via": [0, 0, 0]}]) == ("steps", 0, "target")
    assert loc_of(good, goal={"q": Q0.tolist()}) == ("goal",)
    req = parse_task(body, model)
    assert isinstance(req, TaskRequest) and len(req.steps) == 3 and req.time_limit == 5.0


def test_an_arc_whose_via_is_on_its_chord_is_named_when_planned(ur5):
    model, cm = ur5
    p = ur5_fk(Q1)[0, :3, 3]
    steps = [{"type": "line", "target": (p + [0, 0, -20.0]).tolist()},
             {"type": "arc", "via": (p + [0, 0, -40.0]).tolist(),
              "target": (p + [0, 0, -60.0]).tolist()}]
    with pytest.raises(FieldError) as err:
        plan_task(MotionChecker(cm), Q1, steps, time_limit=5.0)
    assert err.value.loc == ("steps", 1, "via")


def test_a_step_type_is_one_row_of_the_table(ur5, monkeypatch):
    """A toy step ("wait": stays where it is) added as one row plans with the others."""
    model, cm = ur5

    class Wait:
        type = "wait"

        def plan(self, ctx, q):
            from planning.motion.task import _Outcome

            return _Outcome("ok", "ok", np.vstack([q, q]), "wait")

    monkeypatch.setitem(STEP_TYPES, "wait", StepType("wait", (), lambda *a: Wait()))
    res = plan_task(MotionChecker(cm), Q0, [{"type": "wait"}] + move_line_move()[:1],
                    time_limit=5.0)
    assert res.status == "ok" and [s.type for s in res.steps] == ["wait", "move"]
    assert (res.steps[0].first, res.steps[0].last) == (0, 1)
    with pytest.raises(FieldError) as err:
        plan_task(MotionChecker(cm), Q0, [{"type": "wait", "for": 2}], time_limit=1.0)
    assert err.value.loc == ("steps", 0, "for")


def test_progress_goes_step_by_step_and_may_stop_the_task(ur5):
    model, cm = ur5
    seen: list[float] = []
    res = plan_task(MotionChecker(cm), Q0, move_line_move(), time_limit=5.0,
                    progress=seen.append)
    assert res.status == "ok"
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen == sorted(seen)
    assert {1 / 3, 2 / 3} <= set(seen)

    class Stop(Exception):
        pass

    def stop(fraction: float) -> None:
        if fraction >= 2 / 3:
            raise Stop

    with pytest.raises(Stop):
        plan_task(MotionChecker(cm), Q0, move_line_move(), time_limit=5.0, progress=stop)


# ---- carried objects and kept constraints --------------------------------------------------
def _ball_below_the_tool(radius: float = 50.0, drop: float = 120.0) -> dict:
    """An attach step: a ball ``drop`` mm below the tool point at Q1, in the tool frame."""
    T = ur5_fk(Q1)[0]
    pose = np.eye(4)
    pose[:3, 3] = T[:3, :3].T @ np.array([0.0, 0.0, -drop])
    return {"type": "attach", "object": {"type": "sphere", "id": "ball", "radius": radius},
            "link": "tool", "pose": pose.tolist()}


def _low_block(top_below_p1: float) -> CollisionScene:
    p1 = ur5_fk(Q1)[0, :3, 3]
    pose = np.eye(4)
    pose[:3, 3] = p1 + [0.0, 0.0, -top_below_p1 - 20.0]
    return CollisionScene.from_request({"objects": [
        {"type": "box", "id": "block", "size": [300.0, 300.0, 40.0], "pose": pose.tolist()}]})


def test_a_carried_ball_hits_what_the_bare_arm_clears(ur5):
    """The line down ends 60 mm above the block for the bare arm; with a ball carried 120 mm
    below the tool it runs into the block."""
    model, cm = ur5
    scene = _low_block(210.0)
    p1 = ur5_fk(Q1)[0, :3, 3]
    move, line = ({"type": "move", "goal": {"q": Q1.tolist()}},
                  {"type": "line", "target": (p1 + DROP).tolist(), "orientation": "hold"})
    bare = plan_task(MotionChecker(cm, scene), Q0, [move, line], time_limit=5.0)
    assert bare.status == "ok", bare.message
    carried = plan_task(MotionChecker(cm, scene), Q0, [move, _ball_below_the_tool(), line],
                        time_limit=5.0)
    assert [s.status for s in carried.steps] == ["ok", "ok", "collision"]
    assert carried.steps[1].type == "attach" and "carrying 'ball'" in carried.steps[1].message
    assert ("ball", "block") in [tuple(p) for p in carried.steps[2].pairs]
    # Where the line stopped, the ball (120 mm below the tool, radius 50) is above the
    # block's top (210 mm below p1), checked here from the test's own FK.
    stop = ur5_fk(carried.path[carried.steps[2].last])[0, :3, 3]
    assert stop[2] - 120.0 - 50.0 > p1[2] - 210.0 - 1e-6


def test_a_placed_object_stays_in_the_scene(ur5):
    """Detach with place (the default): the ball stays where it was let go, and the tool's
    line down through that place collides with it; without place it is gone."""
    model, cm = ur5
    p1 = ur5_fk(Q1)[0, :3, 3]
    steps = [{"type": "move", "goal": {"q": Q1.tolist()}}, _ball_below_the_tool(),
             {"type": "detach", "object": "ball"},
             {"type": "line", "target": (p1 + DROP).tolist(), "orientation": "hold"}]
    placed = plan_task(MotionChecker(cm), Q0, steps, time_limit=5.0)
    assert [s.status for s in placed.steps] == ["ok", "ok", "ok", "collision"]
    assert any("ball" in pair for pair in placed.steps[3].pairs)
    steps[2] = {"type": "detach", "object": "ball", "place": False}
    dropped = plan_task(MotionChecker(cm), Q0, steps, time_limit=5.0)
    assert dropped.status == "ok", dropped.message


def test_an_object_taken_where_it_collides_stops_the_task(ur5):
    model, cm = ur5
    scene = _low_block(100.0)            # the ball (down to 170 mm below p1) is in the block
    res = plan_task(MotionChecker(cm, scene), Q0,
                    [{"type": "move", "goal": {"q": Q1.tolist()}}, _ball_below_the_tool()],
                    time_limit=5.0)
    assert res.status == "collision" and res.steps[1].type == "attach"
    assert ("ball", "block") in [tuple(p) for p in res.pairs]


@pytest.mark.parametrize("steps, loc", [
    ([{"type": "detach", "object": "ball"}], ("steps", 0, "object")),
    ([_ball_below_the_tool(), _ball_below_the_tool()], ("steps", 1, "object", "id")),
    ([{"type": "attach", "object": {"type": "sphere", "id": "b", "radius": 10},
       "link": "link9"}], ("steps", 0, "link")),
    ([{"type": "attach"}], ("steps", 0, "object")),
    ([{"type": "move", "goal": {"q": Q1.tolist()},
       "constraints": [{"type": "axis", "direction": [0, 0, -1], "tolerance": 0.0}]}],
     ("steps", 0, "constraints", 0, "tolerance")),
])
def test_bad_carry_and_constraint_steps_name_the_field(ur5, steps, loc):
    model, cm = ur5
    with pytest.raises(FieldError) as err:
        plan_task(MotionChecker(cm), Q0, steps, time_limit=1.0)
    assert tuple(err.value.loc) == loc


def test_a_constrained_move_keeps_the_tool_axis_at_every_state(ur5):
    """A move with an axis constraint: the tool stays within 0.1 rad of straight down at
    every state of the answered path, measured here at fine steps with the test's FK."""
    model, cm = ur5
    start = np.array([0.0, -1.2, 1.5, -math.pi / 2 - 0.3, -math.pi / 2, 0.0])
    goal = start + [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    keep = [{"type": "axis", "direction": [0.0, 0.0, -1.0], "tolerance": 0.1}]
    res = plan_task(MotionChecker(cm), start,
                    [{"type": "move", "goal": {"q": goal.tolist()}, "constraints": keep}],
                    time_limit=10.0, trajectory=False)
    assert res.status == "ok", res.message
    assert res.steps[0].planner == "constrained"
    np.testing.assert_allclose(res.path[-1], goal, atol=1e-9)
    fine = [res.path[:1]]
    for a, b in zip(res.path[:-1], res.path[1:]):
        n = max(1, math.ceil(np.abs(b - a).max() / 0.005))
        fine.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    z = ur5_fk(np.concatenate(fine))[:, :3, 2]
    tilt = np.arccos(np.clip(z @ [0.0, 0.0, -1.0], -1.0, 1.0))
    assert tilt.max() <= 0.1 + 1e-3
    with pytest.raises(FieldError) as err:
        plan_task(MotionChecker(cm), start, [{"type": "move", "goal": {
            "pose": ur5_fk(goal)[0].tolist()}, "constraints": keep}], time_limit=1.0)
    assert tuple(err.value.loc) == ("steps", 0, "goal")
