"""POST /robots/{id}/motion: joint-space motion planning answered at once.

The scene is made here: a ball where the GLT palletizer's tool is half-way between the start
and the goal, so the straight move collides and the planner must go around it. Every path
the service returns is checked again, independently of the planner's own checker, with
``planning.collision.collides`` (exact) at a quarter of the planner's joint step.
"""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.urdf import to_urdf
from planning.collision import CollisionScene, RobotCollisionModel, check, collides
from planning.motion import MotionResult, MotionStatus

pytestmark = pytest.mark.usefixtures("motion_kernels")

ROBOT = "glt_palletizer"
START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
#: Where the tool is half-way (waist at 0): the ball's centre.
MIDDLE = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]
BALL_RADIUS = 150.0


def _ball(radius: float = BALL_RADIUS, name: str = "ball") -> dict:
    p = fk(builtin_model(ROBOT), np.array(MIDDLE))[:3, 3]
    pose = np.eye(4)
    pose[:3, 3] = p
    return {"type": "sphere", "id": name, "radius": radius, "pose": pose.tolist()}


SCENE = {"objects": [_ball()]}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """One app for the module: its compute worker starts once and keeps the models."""
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("motion"),
                              prebuild_collision=False))
    yield TestClient(api)
    api.state.compute.shutdown()


def _plan(client: TestClient, robot: str = ROBOT, **body):
    body = {"start": START, "goal": {"q": GOAL}, "scene": SCENE, "time_limit": 1.0} | body
    return client.post(f"/robots/{robot}/motion", json=body)


def _dense(path: np.ndarray, step: float) -> np.ndarray:
    """The states of a polyline no farther apart than ``step`` on any joint."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def _error(r) -> tuple[list, str]:
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    return detail["loc"], detail["msg"]


# ---- plans ----------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_planned_path_goes_around_the_ball_and_every_segment_is_free(ro_client):
    model = builtin_model(ROBOT)
    cm = RobotCollisionModel.from_model(model)
    scene = CollisionScene.from_request(SCENE)
    # The problem is not trivial: the straight move passes through the ball.
    assert collides(cm, _dense(np.array([START, GOAL]), 0.01), scene, exact=True).any()

    r = _plan(ro_client)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["status"] == "ok" and out["robot"] == ROBOT
    # The answer is the planner's result as it writes it (MotionResult.to_dict), plus the
    # robot: no field dropped or renamed on the way.
    written = MotionResult(MotionStatus.OK, "ok", np.zeros((2, 6))).to_dict(joint_names=[])
    assert set(out) == set(written) | {"robot"}
    joints = [j["name"] for j in ro_client.get(f"/robots/{ROBOT}").json()["joints"]]
    assert out["joints"] == joints
    path = np.array(out["path"])
    assert path.shape[1] == 6 and len(path) >= 3
    np.testing.assert_allclose(path[0], START, atol=1e-12)
    np.testing.assert_allclose(path[-1], GOAL, atol=1e-12)
    np.testing.assert_allclose(out["goal"], GOAL, atol=1e-12)
    assert out["resolution"] == 0.01
    dense = _dense(path, out["resolution"] / 4)
    assert not collides(cm, dense, scene, exact=True).any()
    assert np.all((dense >= model.lower - 1e-9) & (dense <= model.upper + 1e-9))
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    assert out["length"] == pytest.approx(seg, rel=1e-9)
    assert out["min_clearance"] > 0
    assert out["pairs"] == [] and out["stats"]["checks"] > 0
    assert 0 < out["planning_time_s"] < 30
    traj = out["trajectory"]
    t, q = np.array(traj["t"]), np.array(traj["q"])
    assert t[0] == 0 and traj["duration"] == pytest.approx(t[-1]) and np.all(np.diff(t) > 0)
    np.testing.assert_allclose(q[0], START, atol=1e-6)
    np.testing.assert_allclose(q[-1], GOAL, atol=1e-6)
    assert not collides(cm, q, scene, exact=True).any()


def test_without_a_trajectory_and_without_a_scene(ro_client):
    r = _plan(ro_client, scene=None, trajectory=False, planner="rrt_connect")
    out = r.json()
    assert r.status_code == 200 and out["status"] == "ok", r.text
    assert out["trajectory"] is None and out["planner"] == "rrt_connect"
    # Nothing in the way: the straight move itself.
    np.testing.assert_allclose(out["path"], [START, GOAL], atol=1e-12)


def test_a_goal_pose_is_reached_through_the_robot_model(ro_client):
    model = builtin_model(ROBOT)
    T_world_tool = fk(model, np.array(GOAL))
    r = _plan(ro_client, goal={"pose": T_world_tool.tolist()})
    out = r.json()
    assert r.status_code == 200 and out["status"] == "ok", r.text
    reached = fk(model, np.array(out["path"][-1]))
    np.testing.assert_allclose(reached[:3, 3], T_world_tool[:3, 3], atol=1e-2)
    np.testing.assert_allclose(reached[:3, :3], T_world_tool[:3, :3], atol=1e-5)
    np.testing.assert_allclose(out["goal"], out["path"][-1], atol=1e-12)


def test_a_start_in_collision_names_the_pairs(ro_client):
    r = _plan(ro_client, start=MIDDLE)
    out = r.json()
    assert r.status_code == 200, r.text
    assert out["status"] == "start_in_collision"
    assert out["path"] == [] and out["trajectory"] is None
    assert out["pairs"] and all(len(p) == 2 for p in out["pairs"])
    assert any("ball" in p for p in out["pairs"])


def test_a_margin_counts_near_misses_as_collisions(ro_client):
    cm = RobotCollisionModel.from_model(builtin_model(ROBOT))
    report = check(cm, np.array(START), CollisionScene.from_request(SCENE),
                   self_collision=False, exact_distance=True)
    gap = float(report.distance)  # mm between the robot at the start and the ball
    assert gap > 20
    near = _plan(ro_client, margin=gap / 2, self_collision=False, trajectory=False).json()
    assert near["status"] == "ok", near["message"]
    r = _plan(ro_client, margin=gap + 10, self_collision=False, trajectory=False)
    assert r.status_code == 200 and r.json()["status"] == "start_in_collision", r.text
    assert any("ball" in p for p in r.json()["pairs"])


def test_an_unreachable_goal_pose_is_a_status(ro_client):
    T = np.eye(4)
    T[:3, 3] = [100_000.0, 0.0, 0.0]  # 100 m away: beyond the arm's reach
    r = _plan(ro_client, goal={"pose": T.tolist()})
    out = r.json()
    assert r.status_code == 200, r.text
    assert out["status"] == "goal_unreachable" and out["path"] == []
    assert out["message"]


@pytest.mark.slow
def test_a_stored_scene_by_id(client):
    stored = {"id": "motion_cell", "objects": [_ball(name="pillar")]}
    assert client.post("/scenes", json=stored).status_code == 201
    out = _plan(client, scene="motion_cell").json()
    assert out["status"] == "ok"
    cm = RobotCollisionModel.from_model(builtin_model(ROBOT))
    scene = CollisionScene.from_request({"objects": stored["objects"]})
    assert not collides(cm, _dense(np.array(out["path"]), 0.0025), scene, exact=True).any()
    blocked = _plan(client, scene="motion_cell", start=MIDDLE).json()
    assert blocked["status"] == "start_in_collision"
    assert any("pillar" in p for p in blocked["pairs"])


# ---- errors ---------------------------------------------------------------------------------
def test_unknown_robot_and_scene_are_404(ro_client):
    r = _plan(ro_client, robot="no_such_robot")
    assert r.status_code == 404 and r.json()["detail"][0]["loc"] == ["path", "robot_id"]
    r = _plan(ro_client, scene="no_such_scene")
    assert r.status_code == 404 and "no_such_scene" in r.json()["detail"][0]["msg"]


@pytest.mark.parametrize("body, loc", [
    ({"start": [0.0] * 5}, ["body", "start"]),
    ({"start": [0.0] * 7}, ["body", "start"]),
    ({"goal": {"q": [0.0] * 5}}, ["body", "goal", "q"]),
    ({"goal": {"pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}},
     ["body", "goal", "pose"]),
    ({"goal": {"pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]}},
     ["body", "goal", "pose"]),
    ({"goal": {"pose": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}}, ["body", "goal", "pose"]),
    ({"goal": {"q": GOAL, "pose": np.eye(4).tolist()}}, ["body", "goal"]),
    ({"goal": {}}, ["body", "goal"]),
    ({"resolution": 0}, ["body", "resolution"]),
    ({"resolution": 0.6}, ["body", "resolution"]),
    ({"time_limit": 0}, ["body", "time_limit"]),
    ({"time_limit": 2.5}, ["body", "time_limit"]),
    ({"planner": "prm"}, ["body", "planner"]),
    ({"margin": -1}, ["body", "margin"]),
    ({"seed": -1}, ["body", "seed"]),
    ({"speed": 1}, ["body", "speed"]),
    ({"scene": {"objects": [{"type": "sphere", "radius": -5}]}},
     ["body", "scene", "objects", 0, "radius"]),
    ({"scene": {"boxes": []}}, ["body", "scene", "boxes"]),
])
def test_bad_fields_are_422_naming_them(ro_client, body, loc):
    assert _error(_plan(ro_client, **body))[0] == loc


def test_non_finite_numbers_are_422(ro_client):
    text = ('{"start": [NaN, 0, 0, 0, 0, 0], "goal": {"q": [0, 0, 0, 0, 0, 0]}}')
    r = ro_client.post(f"/robots/{ROBOT}/motion", content=text,
                    headers={"Content-Type": "application/json"})
    assert _error(r)[0] == ["body", "start", 0]
    text = ('{"start": [0, 0, 0, 0, 0, 0], "goal": {"q": [0, 0, 0, 0, 0, 0]}, '
            '"time_limit": Infinity}')
    r = ro_client.post(f"/robots/{ROBOT}/motion", content=text,
                    headers={"Content-Type": "application/json"})
    assert _error(r)[0] == ["body", "time_limit"]


def test_the_time_limit_message_points_at_jobs(ro_client):
    loc, msg = _error(_plan(ro_client, time_limit=5))
    assert loc == ["body", "time_limit"] and "2" in msg


# ---- imported robots ------------------------------------------------------------------------
def _imported_urdf() -> str:
    """The GLT palletizer as URDF, with box and cylinder collision shapes on two links."""
    text = to_urdf(builtin_model(ROBOT))
    shapes = {"link_2": '<box size="0.6 0.12 0.12"/>',
              "link_3": '<cylinder radius="0.05" length="0.5"/>'}
    for link, shape in shapes.items():
        text = text.replace(f'<link name="{link}" />',
                            f'<link name="{link}"><collision><geometry>{shape}</geometry>'
                            '</collision></link>')
    return text


@pytest.mark.slow
def test_an_imported_robot_plans_with_its_stored_collision_model(client):
    r = client.post("/robots/import", files={"file": ("glt.urdf", _imported_urdf().encode(),
                                                      "text/xml")},
                    data={"id": "glt_imported"})
    assert r.status_code == 201, r.text
    out = _plan(client, robot="glt_imported", trajectory=False).json()
    assert out["status"] == "ok", out
    registry = client.app.state.registry
    cm = registry.collision_model("glt_imported")
    assert cm.kind == "imported"
    scene = CollisionScene.from_request(SCENE)
    assert not collides(cm, _dense(np.array(out["path"]), 0.0025), scene, exact=True).any()
