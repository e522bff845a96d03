"""POST /robots/{id}/motion and the motion job with ``steps``: a task of moves and lines
planned in turn, answered as one path and one trajectory with a status per step.

The arm is a UR5-like standard D-H robot added through ``POST /robots``; the tool poses of
the answered states are recomputed here with a D-H product of the test's own."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app

pytestmark = pytest.mark.usefixtures("motion_kernels")

PI = math.pi
ROBOT = "ur5_like"
#: UR5 standard D-H (a, alpha, d), mm.
UR5_DH = [(0.0, PI / 2, 89.159), (-425.0, 0.0, 0.0), (-392.25, 0.0, 0.0),
          (0.0, PI / 2, 109.15), (0.0, -PI / 2, 94.65), (0.0, 0.0, 82.3)]
UR5 = {"id": ROBOT, "name": "UR5-like", "convention": "sdh",
       "joints": [{"name": f"j{i + 1}", "type": "revolute", "a": a, "alpha": al, "d": d,
                   "lower": -2 * PI, "upper": 2 * PI}
                  for i, (a, al, d) in enumerate(UR5_DH)]}
Q0 = [0.0, -1.2, 1.5, -1.9, -1.57, 0.3]
Q1 = [0.6, -1.0, 1.3, -1.9, -1.57, 0.3]
DROP = np.array([0.0, 0.0, -150.0])
ENDED = ("succeeded", "failed", "cancelled")


def ur5_fk(q) -> np.ndarray:
    """Tool poses ``(n, 4, 4)`` of ``q (n, 6)``: RotZ(q) TransZ(d) TransX(a) RotX(alpha)."""
    out = []
    for row in np.atleast_2d(np.asarray(q, dtype=float)):
        T = np.eye(4)
        for (a, alpha, d), th in zip(UR5_DH, row):
            ct, st, ca, sa = math.cos(th), math.sin(th), math.cos(alpha), math.sin(alpha)
            T = T @ np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                              [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        out.append(T)
    return np.array(out)


P1 = ur5_fk(Q1)[0, :3, 3]
STEPS = [{"type": "move", "goal": {"q": Q1}},
         {"type": "line", "target": (P1 + DROP).tolist(), "orientation": "hold"},
         {"type": "move", "goal": {"q": Q0}}]


def _block() -> dict:
    """A slab 100 mm below the tool at Q1: the line down runs into it."""
    pose = np.eye(4)
    pose[:3, 3] = P1 + [0.0, 0.0, -160.0]
    return {"type": "box", "id": "block", "size": [300.0, 300.0, 40.0], "pose": pose.tolist()}


@pytest.fixture(scope="module")
def served(tmp_path_factory) -> Iterator[TestClient]:
    """An app with its job backend (2 local workers) and the UR5-like robot added."""
    settings = Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("steps"), workers=2,
                        prebuild_collision=False)
    with TestClient(create_app(settings)) as c:
        assert c.post("/robots", json=UR5).status_code == 201
        yield c


def _plan(client: TestClient, **body):
    return client.post(f"/robots/{ROBOT}/motion", json={"start": Q0, "time_limit": 2.0} | body)


def _error(r) -> tuple[list, str]:
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert len(detail) == 1, detail
    return detail[0]["loc"], detail[0]["msg"]


def _timeless(answer: dict) -> dict:
    """The answer without its measured times."""
    out = {k: v for k, v in answer.items() if k not in ("planning_time_s", "simplify_time_s")}
    out["steps"] = [{k: v for k, v in s.items() if k != "planning_time_s"}
                    for s in answer["steps"]]
    return out


def test_a_move_a_line_and_a_move_answer_one_path_and_one_trajectory(served):
    r = _plan(served, steps=STEPS)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "ok" and out["message"] == "ok"
    assert out["robot"] == ROBOT and out["joints"] == [f"j{i}" for i in range(1, 7)]
    assert out["planner"] == "task"
    path = np.array(out["path"])
    steps = out["steps"]
    assert [(s["index"], s["type"], s["status"]) for s in steps] == [
        (0, "move", "ok"), (1, "line", "ok"), (2, "move", "ok")]
    # Continuous: each step starts at the state the one before ended at.
    assert steps[0]["states"][0] == 0 and steps[-1]["states"][1] == len(path) - 1
    for a, b in zip(steps, steps[1:]):
        assert a["states"][1] == b["states"][0]
    np.testing.assert_allclose(path[0], Q0, atol=1e-12)
    np.testing.assert_allclose(path[steps[0]["states"][1]], Q1, atol=1e-12)
    np.testing.assert_allclose(path[-1], Q0, atol=1e-12)
    assert out["goal"] == out["path"][-1]
    # The line's states: on the line (FK recomputed here), joints moving less than the jump
    # threshold from state to state, the whole 150 mm.
    first, last = steps[1]["states"]
    line = path[first:last + 1]
    assert np.abs(np.diff(line, axis=0)).max() <= 0.3
    P = ur5_fk(line)[:, :3, 3]
    d = DROP / np.linalg.norm(DROP)
    rel = P - P1
    off = np.linalg.norm(rel - (rel @ d)[:, None] * d, axis=1)
    assert off.max() <= 0.1 and rel[-1] @ d == pytest.approx(150.0, abs=0.1)
    assert steps[1]["fraction"] == 1.0 and steps[0]["fraction"] is None
    assert steps[1]["deviation"] < 0.5
    # One trajectory over the whole task, continuous, from the start back to it.
    traj = out["trajectory"]
    q = np.array(traj["q"])
    assert len(traj["t"]) == 200 and traj["duration"] == traj["t"][-1]
    np.testing.assert_allclose(q[0], Q0, atol=1e-9)
    np.testing.assert_allclose(q[-1], Q0, atol=1e-9)
    assert np.abs(np.diff(q, axis=0)).max() < 0.2
    assert out["min_clearance"] is not None and out["length"] > 0


def test_a_line_into_an_obstacle_answers_its_status_fraction_and_the_path_before(served):
    scene = {"objects": [_block()]}
    alone = _plan(served, goal={"q": Q1}, scene=scene).json()
    r = _plan(served, steps=STEPS, scene=scene)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "collision" and out["message"].startswith("step 1 (line): ")
    assert [s["status"] for s in out["steps"]] == ["ok", "collision"]
    line = out["steps"][1]
    assert 0.0 < line["fraction"] < 1.0
    assert any("block" in p for p in line["pairs"])
    # The move's path as a single move plans it, then the line up to the block.
    a, b = out["steps"][0]["states"]
    assert out["path"][a:b + 1] == alone["path"]
    assert line["states"] == [b, len(out["path"]) - 1]
    reached = ur5_fk(out["path"][-1])[0, :3, 3]
    assert 0.0 < P1[2] - reached[2] < 100.0
    assert out["trajectory"] is None and out["goal"] is None


def test_goal_and_steps_together_are_refused_naming_goal(served):
    loc, msg = _error(_plan(served, goal={"q": Q1}, steps=STEPS))
    assert loc == ["body", "goal"] and "not both" in msg


def test_a_bad_field_of_a_step_is_named_with_the_step(served):
    bad = [STEPS[0], STEPS[1], {"type": "line", "target": [100.0, 200.0]}]
    loc, msg = _error(_plan(served, steps=bad))
    assert loc == ["body", "steps", 2, "target"] and "point" in msg
    loc, _ = _error(_plan(served, steps=[STEPS[0], STEPS[1], {**STEPS[2], "speed": 1}]))
    assert loc == ["body", "steps", 2, "speed"]
    loc, _ = _error(_plan(served, steps=[STEPS[0], STEPS[1], {"type": "move",
                                                               "goal": {"q": [0.0] * 5}}]))
    assert loc == ["body", "steps", 2, "goal", "q"]
    loc, _ = _error(_plan(served, steps=[STEPS[0]] * 101))
    assert loc == ["body", "steps"]


def test_attach_and_detach_over_rest(served):
    """A ball taken at the tool, carried along the line, let go: the steps answer in order;
    a detach of what no step took is a 422 naming its object."""
    ahead = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 100.0], [0, 0, 0, 1]]  # 100 mm out
    ball = {"type": "attach", "object": {"type": "sphere", "id": "ball", "radius": 30},
            "link": "tool", "pose": ahead}
    r = _plan(served, steps=[STEPS[0], ball, STEPS[1], {"type": "detach", "object": "ball"}])
    assert r.status_code == 200, r.text
    answer = r.json()
    assert answer["status"] == "ok", answer["message"]
    assert [s["type"] for s in answer["steps"]] == ["move", "attach", "line", "detach"]
    loc, msg = _error(_plan(served, steps=[STEPS[0], {"type": "detach", "object": "box"}]))
    assert loc == ["body", "steps", 1, "object"] and "not carried" in msg


def test_a_body_without_steps_is_answered_as_before(served):
    """Without steps a missing or null goal is the error it always was."""
    r = _plan(served)
    assert r.status_code == 422
    assert r.json()["detail"] == [{"loc": ["body", "goal"], "msg": "Field required",
                                   "type": "missing"}]
    r = _plan(served, goal=None)
    assert r.json()["detail"] == [{"loc": ["body", "goal"], "msg": "Input should be a valid "
                                   "dictionary or instance of GoalIn", "type": "model_type"}]
    out = _plan(served, goal={"q": Q1}).json()
    assert out["status"] == "ok" and "steps" not in out and out["planner"] == "rrt_connect"


def test_the_motion_job_with_steps_answers_as_the_endpoint(served):
    direct = _plan(served, steps=STEPS).json()
    r = served.post("/jobs", json={"kind": "motion", "params": {
        "robot": ROBOT, "start": Q0, "steps": STEPS, "time_limit": 2.0}})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    deadline = time.monotonic() + 120
    while (job := served.get(f"/jobs/{job_id}").json())["status"] not in ENDED:
        assert time.monotonic() < deadline
        time.sleep(0.1)
    assert job["status"] == "succeeded", job
    result = served.get(f"/jobs/{job_id}/result").json()
    assert _timeless(result) == _timeless(direct)
    # Checked at submission: a bad step is a 422 naming it within the params.
    r = served.post("/jobs", json={"kind": "motion", "params": {
        "robot": ROBOT, "start": Q0, "steps": [STEPS[0], {"type": "line"}]}})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "params", "steps", 1, "target"]
    r = served.post("/jobs", json={"kind": "motion", "params": {
        "robot": ROBOT, "start": Q0, "goal": {"q": Q1}, "steps": STEPS}})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "params", "goal"]
