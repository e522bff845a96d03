"""The ``motion`` job kind: one problem or a batch sharing robot, scene and settings; progress
per problem; cancellation; a stored scene filled in at submission; the submission checked
against the robot (422 naming the problem's field, 404 for an unknown robot or scene).

Run in this process as a worker runs it (``execute``) where the job machinery is not the
point, and through a served app with its local workers otherwise. Every returned path is
checked again with ``planning.collision.collides`` (exact) at a quarter of the planner's
joint step.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.jobs.catalog import KINDS
from app.jobs.kinds import JobCancelled, JobPayload, execute
from app.jobs.motion_kinds import MAX_MOTION_PARAMS_BYTES
from kinematics.fk import fk
from kinematics.library import builtin_model
from kinematics.urdf import to_urdf
from planning.collision import CollisionScene, RobotCollisionModel, collides
from planning.motion.request import MAX_PROBLEMS

from .conftest import wait_for

pytestmark = pytest.mark.usefixtures("motion_kernels")

ROBOT = "glt_palletizer"
START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
MIDDLE = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]


def _ball(name: str = "ball", radius: float = 150.0) -> dict:
    """A ball where the tool is half-way between START and GOAL."""
    pose = np.eye(4)
    pose[:3, 3] = fk(builtin_model(ROBOT), np.array(MIDDLE))[:3, 3]
    return {"type": "sphere", "id": name, "radius": radius, "pose": pose.tolist()}


SCENE = {"objects": [_ball()]}
#: Three problems: around the ball, back, and one whose start collides.
PROBLEMS = [{"start": START, "goal": {"q": GOAL}},
            {"start": GOAL, "goal": {"q": START}, "seed": 7},
            {"start": MIDDLE, "goal": {"q": GOAL}, "time_limit": 0.5}]


def _run(params: dict, progress=lambda f, m: None) -> dict:
    """The stored JSON of a motion job run as a worker runs it."""
    spec = KINDS["motion"]
    checked = spec.load_params(params)
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(params["robot"]).to_dict())
    return json.loads(execute("motion", payload.model_dump(mode="json"), progress))


def _dense(path: np.ndarray, step: float) -> np.ndarray:
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def _assert_free(result: dict, objects: list[dict]) -> None:
    cm = RobotCollisionModel.from_model(builtin_model(ROBOT))
    scene = CollisionScene.from_request({"objects": objects})
    path = np.array(result["path"])
    assert len(path) >= 2
    assert not collides(cm, _dense(path, result["resolution"] / 4), scene, exact=True).any()


# ---- in this process ------------------------------------------------------------------------
def test_one_problem_answers_its_result_with_the_robot_and_joints():
    out = _run({"robot": ROBOT, "scene": SCENE, "start": START, "goal": {"q": GOAL},
                "time_limit": 2.0})
    assert out["status"] == "ok" and out["robot"] == ROBOT
    assert out["joints"] == [j.name for j in builtin_model(ROBOT).joints]
    assert "problems" not in out and "summary" not in out
    np.testing.assert_allclose(out["path"][0], START, atol=1e-12)
    np.testing.assert_allclose(out["path"][-1], GOAL, atol=1e-12)
    assert len(out["path"]) >= 3  # around the ball, not through it
    _assert_free(out, SCENE["objects"])
    assert out["trajectory"]["duration"] > 0


def test_a_batch_answers_each_result_and_a_summary_with_progress_per_problem():
    reports: list[tuple[float, str]] = []
    out = _run({"robot": ROBOT, "scene": SCENE, "problems": PROBLEMS, "time_limit": 2.0,
                "trajectory": False},
               lambda f, m: reports.append((f, m)))
    assert set(out) == {"robot", "joints", "problems", "summary"}
    first, back, blocked = out["problems"]
    assert first["status"] == back["status"] == "ok"
    for r in (first, back):
        _assert_free(r, SCENE["objects"])
    np.testing.assert_allclose(back["path"][-1], START, atol=1e-12)
    assert blocked["status"] == "start_in_collision"
    assert any("ball" in pair for pair in blocked["pairs"])
    summary = out["summary"]
    assert summary["solved"] == 2 and summary["total"] == 3
    assert summary["median_length"] == pytest.approx(
        float(np.median([first["length"], back["length"]])))
    assert summary["median_planning_time_s"] == pytest.approx(
        float(np.median([r["planning_time_s"] for r in out["problems"]])))
    # Progress: non-decreasing, each problem named, ending at 1.
    fractions = [f for f, _ in reports]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    for k in (1, 2, 3):
        assert any(m == f"problem {k} of 3" for _, m in reports)


def test_a_goal_pose_in_a_job():
    model = builtin_model(ROBOT)
    T_world_tool = fk(model, np.array(GOAL))
    out = _run({"robot": ROBOT, "scene": SCENE, "start": START,
                "goal": {"pose": T_world_tool.tolist()}, "time_limit": 2.0,
                "trajectory": False})
    assert out["status"] == "ok"
    reached = fk(model, np.array(out["path"][-1]))
    np.testing.assert_allclose(reached[:3, 3], T_world_tool[:3, 3], atol=1e-2)
    unreachable = np.eye(4)
    unreachable[:3, 3] = [100_000.0, 0.0, 0.0]
    out = _run({"robot": ROBOT, "start": START, "goal": {"pose": unreachable.tolist()},
                "time_limit": 1.0})
    assert out["status"] == "goal_unreachable" and out["path"] == []


def test_cancelling_stops_a_problem_at_its_next_progress_report():
    calls = []

    def progress(fraction: float, message: str) -> None:
        calls.append(message)
        if calls.count("problem 1 of 3") == 5:
            raise JobCancelled

    with pytest.raises(JobCancelled):
        _run({"robot": ROBOT, "scene": SCENE, "problems": PROBLEMS, "planner": "rrt_star",
              "time_limit": 60.0, "trajectory": False}, progress)
    # rrt_star searches for its whole time limit unless stopped: the first problem was
    # stopped while it searched, and no other problem started.
    assert calls[-1] == "problem 1 of 3"
    assert "problem 2 of 3" not in calls


# ---- through the service --------------------------------------------------------------------
def _submit(client, params: dict, **extra):
    return client.post("/jobs", json={"kind": "motion", "params": params, **extra})


@pytest.mark.slow
def test_a_batch_job_in_a_stored_scene_through_the_service(jobs_client):
    c = jobs_client
    stored = {"id": "motion_cell", "objects": [_ball(name="pillar")]}
    assert c.post("/scenes", json=stored).status_code == 201
    r = _submit(c, {"robot": ROBOT, "scene": "motion_cell", "problems": PROBLEMS[:2],
                    "time_limit": 2.0, "trajectory": False})
    assert r.status_code == 202, r.text
    job = r.json()
    # The job records the geometry it plans in.
    assert job["params"]["scene"]["id"] == "motion_cell"
    assert [o["id"] for o in job["params"]["scene"]["objects"]] == ["pillar"]
    done = wait_for(c, job["id"])
    assert done["status"] == "succeeded", done
    assert done["progress"] == 1.0
    out = c.get(f"/jobs/{job['id']}/result").json()
    assert out["summary"]["solved"] == out["summary"]["total"] == 2, out["problems"]
    for result in out["problems"]:
        _assert_free(result, stored["objects"])


def test_a_running_job_is_cancelled(jobs_client):
    c = jobs_client
    r = _submit(c, {"robot": ROBOT, "scene": SCENE, "start": START, "goal": {"q": GOAL},
                    "planner": "rrt_star", "time_limit": 60.0, "trajectory": False})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    wait_for(c, job_id, statuses=("running",), timeout=60)
    assert c.delete(f"/jobs/{job_id}").status_code == 200
    assert wait_for(c, job_id, timeout=30)["status"] == "cancelled"


def _error(r, status: int = 422) -> tuple[list, str]:
    assert r.status_code == status, r.text
    detail = r.json()["detail"][0]
    return detail["loc"], detail["msg"]


@pytest.mark.parametrize("params, loc", [
    ({"start": [0.0] * 5}, ["body", "params", "start"]),
    ({"goal": {"q": [0.0] * 7}}, ["body", "params", "goal", "q"]),
    ({"goal": {"pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]}},
     ["body", "params", "goal", "pose"]),
    ({"start": None}, ["body", "params", "start"]),
    ({"problems": PROBLEMS}, ["body", "params", "start"]),
    ({"start": None, "goal": None,
      "problems": [PROBLEMS[0], {"start": START, "goal": {"q": [0.0] * 5}}]},
     ["body", "params", "problems", 1, "goal", "q"]),
    ({"start": None, "goal": None, "problems": [{"start": START, "goal": {"q": GOAL}}]
      * (MAX_PROBLEMS + 1)}, ["body", "params", "problems"]),
    ({"time_limit": 61}, ["body", "params", "time_limit"]),
    ({"time_limit": 0}, ["body", "params", "time_limit"]),
    ({"resolution": 0.51}, ["body", "params", "resolution"]),
    ({"planner": "prm"}, ["body", "params", "planner"]),
    ({"scene": {"objects": [{"type": "box", "size": [1, 1]}]}},
     ["body", "params", "scene", "objects", 0, "size"]),
])
def test_bad_params_are_422_naming_the_field(checking_client, params, loc):
    body = {"robot": ROBOT, "start": START, "goal": {"q": GOAL}} | params
    body = {k: v for k, v in body.items() if v is not None}
    assert _error(_submit(checking_client, body))[0] == loc


def test_unknown_robot_and_scene_are_404(jobs_client):
    c = jobs_client
    loc, _ = _error(_submit(c, {"robot": "nope", "start": START, "goal": {"q": GOAL}}), 404)
    assert loc == ["body", "params", "robot"]
    loc, msg = _error(_submit(c, {"robot": ROBOT, "scene": "nope", "start": START,
                                  "goal": {"q": GOAL}}), 404)
    assert loc == ["body", "params", "scene"] and "nope" in msg


@pytest.mark.slow
def test_a_scene_too_big_for_a_job_is_413(jobs_client):
    c = jobs_client
    # Stored meshes filled in at submission take more than a motion job's params may.
    sphere = pytest.importorskip("trimesh").creation.icosphere(subdivisions=6, radius=100.0)
    files = {"file": ("ball.stl", sphere.export(file_type="stl"), "application/sla")}
    assert c.post("/meshes", files=files, data={"id": "big_ball"}).status_code == 201
    objects = [{"type": "mesh", "id": f"ball_{k}", "mesh": "big_ball",
                "pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5000 + 300 * k], [0, 0, 0, 1]]}
               for k in range(3)]
    inline = len(json.dumps([sphere.vertices.tolist(), sphere.faces.tolist()])) * 3
    assert inline > MAX_MOTION_PARAMS_BYTES
    r = _submit(c, {"robot": ROBOT, "scene": {"objects": objects}, "start": START,
                    "goal": {"q": GOAL}})
    assert r.status_code == 413, r.status_code
    assert r.json()["detail"][0]["loc"] == ["body", "params", "scene"]


@pytest.mark.slow
def test_a_small_stored_mesh_is_filled_in(jobs_client):
    c = jobs_client
    box = pytest.importorskip("trimesh").creation.box(extents=(200.0, 200.0, 200.0))
    files = {"file": ("box.stl", box.export(file_type="stl"), "application/sla")}
    assert c.post("/meshes", files=files, data={"id": "crate"}).status_code == 201
    mesh = {"type": "mesh", "id": "crate", "mesh": "crate",
            "pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5000], [0, 0, 0, 1]]}
    r = _submit(c, {"robot": ROBOT, "scene": {"objects": [mesh]}, "start": START,
                    "goal": {"q": GOAL}, "time_limit": 1.0, "trajectory": False})
    assert r.status_code == 202, r.text
    obj = r.json()["params"]["scene"]["objects"][0]
    assert "mesh" not in obj and len(obj["vertices"]) == 8 and len(obj["faces"]) == 12
    loc, _ = _error(_submit(c, {"robot": ROBOT, "scene": {"objects": [{**mesh,
                                                                       "mesh": "nope"}]},
                                "start": START, "goal": {"q": GOAL}}))
    assert loc == ["body", "params", "scene", "objects", 0, "mesh"]


def _meshed_glt_zip() -> bytes:
    """The GLT palletizer as URDF with a trimesh box as its upper arm's collision mesh and a
    capsule as its visual mesh, zipped."""
    import io
    import zipfile

    trimesh = pytest.importorskip("trimesh")
    text = to_urdf(builtin_model(ROBOT)).replace(
        '<link name="link_2" />',
        '<link name="link_2"><collision><geometry><mesh filename="meshes/upper.stl"/>'
        '</geometry></collision><visual><geometry><mesh filename="meshes/look.stl"/>'
        '</geometry></visual></link>')
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt/glt.urdf", text)
        z.writestr("glt/meshes/upper.stl",
                   trimesh.creation.box(extents=(0.6, 0.15, 0.15)).export(file_type="stl"))
        z.writestr("glt/meshes/look.stl",      # visual only: stays with the service
                   trimesh.creation.capsule(radius=0.07, height=0.5).export(file_type="stl"))
    return buf.getvalue()


@pytest.mark.slow
def test_an_imported_robot_plans_in_a_job_with_its_meshes(jobs_client):
    """The job carries the imported robot's description, collision model and collision
    meshes to its worker: the plan there is checked on the mesh, as the service's own."""
    c = jobs_client
    r = c.post("/robots/import", files={"file": ("glt.zip", _meshed_glt_zip(),
                                                 "application/zip")},
               data={"id": "glt_urdf"})
    assert r.status_code == 201, r.text
    registry = c.app.state.registry
    registry.collision_model("glt_urdf")        # built (the import prebuilds it too)
    r = _submit(c, {"robot": "glt_urdf", "scene": SCENE, "problems": PROBLEMS[:2],
                    "trajectory": False})
    assert r.status_code == 202, r.text
    done = wait_for(c, r.json()["id"])
    assert done["status"] == "succeeded", done
    out = c.get(f"/jobs/{r.json()['id']}/result").json()
    assert out["summary"]["solved"] == 2, out["problems"]
    cm = registry.collision_model("glt_urdf")
    assert cm.kind == "imported" and "link_2" in cm.names
    scene = CollisionScene.from_request(SCENE)
    for result in out["problems"]:
        assert not collides(cm, _dense(np.array(result["path"]), 0.0025), scene,
                            exact=True).any()


def test_the_warm_up_builds_the_exact_shapes_and_triangles_of_a_meshed_robot():
    """``motion_kinds.warm_up`` (before a worker's first plan of a kind of checker) builds
    the imported robot's exact stage (FCL's trees of its meshes) and the compiled stage's
    triangles, once per model: the first plan that meets a flagged state does not."""
    from app.jobs import motion_kinds
    from kinematics.urdf_import import import_robot
    from planning.motion.checker import TRIANGLES_MAX
    from planning.motion.request import robot_problem

    robot = import_robot(_meshed_glt_zip(), "glt.zip", robot_id="glt_warm")
    cm = RobotCollisionModel.from_imported(robot)
    scene = CollisionScene.from_request(SCENE)
    req = robot_problem(robot.model, START, {"q": GOAL})
    assert "_exact" not in cm.__dict__ and TRIANGLES_MAX not in \
        cm.__dict__.get("_mesh_triangles", {})
    motion_kinds.warm_up(req, cm, scene)
    assert "_exact" in cm.__dict__
    tri = cm.__dict__["_mesh_triangles"][TRIANGLES_MAX]
    k = cm.names.index("link_2")
    assert tri.whole[k] and tri.first[k + 1] - tri.first[k] == 12      # the box's mesh
