"""``GET /jobs/{id}/replay.html``: a finished job's motion as one self-contained HTML page.

Results are written to the store as a worker leaves them (checked against the kind's result
model first), with joint samples chosen here; the page's embedded data (the JSON in its
``replay-data`` script) is read back and its poses compared with FK computed here. The page
running in a browser: ``tests/web/test_replay_browser.py``.
"""

from __future__ import annotations

import io
import json
import re
import zipfile

import numpy as np
import pytest
from fastapi.testclient import TestClient
from stored_jobs import store_job as _store

from app.replay import MAX_FRAMES, MAX_TRIANGLES, decimate
from kinematics.fk import fk, fk_frames, joint_axes
from kinematics.library import builtin_model
from kinematics.rigs import builtin_rig
from kinematics.urdf import to_urdf

GLT = "glt_palletizer"
GLT_START = np.array([-1.0, 0.3, -0.3, 0.0, 0.5, 0.0])
GLT_GOAL = np.array([1.0, 0.3, -0.3, 0.0, 0.5, 0.0])
DATA = re.compile(r'<script id="replay-data" type="application/json">(.*?)</script>', re.S)
#: Rounding of the embedded poses: rotation entries (1e-5) and lengths (0.01 mm).
ROT_TOL, MM_TOL = 1e-5, 0.01


def _page(client: TestClient, url: str) -> tuple[str, dict]:
    r = client.get(url)
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/html")
    (found,) = DATA.findall(r.text)
    return r.text, json.loads(found)


def _detail(r) -> dict:
    (detail,) = r.json()["detail"]
    return detail


def _poses(data: dict, key: str) -> np.ndarray:
    """The embedded poses of ``key`` as ``(frames, 4, 4)``."""
    A = np.asarray(data["poses"][key], dtype=float).reshape(-1, 3, 4)
    out = np.zeros((len(A), 4, 4))
    out[:, :3] = A
    out[:, 3, 3] = 1.0
    return out


def _close(got: np.ndarray, want: np.ndarray) -> None:
    np.testing.assert_allclose(got[..., :3, :3], want[..., :3, :3], rtol=0, atol=ROT_TOL)
    np.testing.assert_allclose(got[..., :3, 3], want[..., :3, 3], rtol=0, atol=MM_TOL)


# ---- a motion job of the palletizer in a scene ----------------------------------------------
def _glt_motion(n: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """``n`` samples from the start to the goal (a cosine ramp) as a motion job's result."""
    t = np.linspace(0.0, 2.5, n)
    s = 0.5 - 0.5 * np.cos(np.pi * t / t[-1])
    q = GLT_START + np.outer(s, GLT_GOAL - GLT_START)
    names = [j.name for j in builtin_model(GLT).joints]
    result = {"robot": GLT, "joints": names, "status": "ok", "message": "ok",
              "path": [GLT_START.tolist(), GLT_GOAL.tolist()], "length": 2.0,
              "planning_time_s": 0.1, "simplify_time_s": 0.0, "min_clearance": 100.0,
              "goal": GLT_GOAL.tolist(), "pairs": [], "planner": "rrt_connect",
              "resolution": 0.01, "stats": {},
              "trajectory": {"t": t.tolist(), "q": q.tolist(), "qd": np.zeros_like(q).tolist(),
                             "qdd": np.zeros_like(q).tolist(), "duration": float(t[-1])}}
    return t, q, result


def _pose(x: float, y: float, z: float) -> list[list[float]]:
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


SCENE = {"objects": [
    {"type": "box", "id": "pallet", "size": [400, 300, 200], "pose": _pose(900, 0, 100)},
    {"type": "sphere", "id": "ball", "radius": 100, "pose": _pose(0, -900, 300)},
    {"type": "cylinder", "id": "post", "radius": 50, "height": 800, "pose": _pose(-700, 0, 400)},
    {"type": "capsule", "id": "pipe", "a": [0, 0, 0], "b": [0, 500, 0], "radius": 40,
     "pose": _pose(600, 600, 900)},
    {"type": "mesh", "id": "plate", "vertices": [[0, 0, 0], [300, 0, 0], [0, 300, 0]],
     "faces": [[0, 1, 2]], "pose": _pose(-600, -600, 0)},
    {"type": "points", "id": "scan", "radius": 10,
     "points": [[-800, 0, 0], [-800, 100, 0], [-800, 200, 50]]},
]}


@pytest.fixture
def glt_job(client) -> tuple[TestClient, np.ndarray, np.ndarray]:
    t, q, result = _glt_motion(120)
    params = {"robot": GLT, "start": GLT_START.tolist(), "goal": {"q": GLT_GOAL.tolist()},
              "scene": SCENE}
    _store(client, "glt", "motion", params, result)
    return client, t, q


def test_the_page_is_one_file_without_any_url(glt_job):
    client, t, _ = glt_job
    text, data = _page(client, "/jobs/glt/replay.html")
    assert not re.search(r"https?://", text)
    # nothing fetched: no src or href, no stylesheet or module import
    assert not re.search(r"\b(src|href)\s*=", text, re.I)
    assert "<link" not in text and "import(" not in text and "@import" not in text
    assert text.count("<script") == 2  # the data and the player
    assert 'filename="glt-replay.html"' in client.get(
        "/jobs/glt/replay.html").headers["content-disposition"]
    assert data["frames"] == len(data["t"]) == len(t) == 120
    np.testing.assert_allclose(data["t"], t, atol=1e-6)
    assert (data["job"], data["kind"], data["robots"]) == ("glt", "motion", [GLT])


def test_the_arm_is_posed_by_fk_at_every_frame(glt_job):
    client, _, q = glt_job
    model = builtin_model(GLT)
    _, data = _page(client, "/jobs/glt/replay.html")
    frames = fk_frames(model, q)  # (N, dof + 1, 4, 4)
    for key in [f"{GLT}/base", f"{GLT}/tool"] + [f"{GLT}/link_{i}" for i in range(6)]:
        assert key in data["links"] and len(data["poses"][key]) == 12 * len(q)
    names = {n["name"] for n in data["nodes"]}
    assert {f"{GLT}/base", f"{GLT}/link_0", f"{GLT}/joint_5", f"{GLT}/tool/z"} <= names
    for k in (0, 37, 80, len(q) - 1):
        _close(_poses(data, f"{GLT}/tool")[k], fk(model, q[k]))
        _close(_poses(data, f"{GLT}/base")[k], frames[k, 0])
        _, points, _ = joint_axes(model, q[k:k + 1])
        for i in range(6):
            # the link cylinder's unit segment spans frame origin i to frame origin i + 1
            A = _poses(data, f"{GLT}/link_{i}")[k]
            np.testing.assert_allclose(A[:3, 3], frames[k, i, :3, 3], atol=MM_TOL)
            np.testing.assert_allclose(A[:3, 3] + A[:3, 2], frames[k, i + 1, :3, 3], atol=0.05)
            np.testing.assert_allclose(_poses(data, f"{GLT}/joint_{i}")[k, :3, 3],
                                       points[0, i], atol=MM_TOL)
    # the tool path: FK of every frame
    (path,) = [x for x in data["lines"] if x["name"] == f"{GLT}/tool_path"]
    np.testing.assert_allclose(np.reshape(path["pts"], (-1, 3)), fk(model, q)[:, :3, 3],
                               atol=MM_TOL)


def test_the_scene_is_drawn_where_its_objects_are(glt_job):
    client, _, _ = glt_job
    _, data = _page(client, "/jobs/glt/replay.html")
    nodes = {n["name"]: n for n in data["nodes"]}
    assert {"scene/pallet", "scene/ball", "scene/post", "scene/pipe", "scene/plate"} <= set(nodes)
    assert all(nodes[k]["pose"] is None for k in nodes if k.startswith("scene/"))

    def verts(name: str) -> np.ndarray:
        return np.reshape(nodes[name]["v"], (-1, 3))

    np.testing.assert_allclose(verts("scene/pallet").min(axis=0), [700, -150, 0], atol=MM_TOL)
    np.testing.assert_allclose(verts("scene/pallet").max(axis=0), [1100, 150, 200], atol=MM_TOL)
    assert len(nodes["scene/pallet"]["f"]) == 12 * 3
    r = np.linalg.norm(verts("scene/ball") - [0, -900, 300], axis=1)
    np.testing.assert_allclose(r, 100.0, atol=MM_TOL)
    post = verts("scene/post")
    np.testing.assert_allclose([post[:, 2].min(), post[:, 2].max()], [0, 800], atol=MM_TOL)
    pipe = verts("scene/pipe")
    np.testing.assert_allclose(pipe.min(axis=0), [560, 560, 860], atol=0.5)
    np.testing.assert_allclose(pipe.max(axis=0), [640, 1140, 940], atol=0.5)
    np.testing.assert_allclose(verts("scene/plate"), [[-600, -600, 0], [-300, -600, 0],
                                                      [-600, -300, 0]], atol=MM_TOL)
    (scan,) = data["points"]
    assert scan["name"] == "scene/scan" and scan["radius"] == 10
    np.testing.assert_allclose(np.reshape(scan["pts"], (-1, 3)),
                               SCENE["objects"][5]["points"], atol=MM_TOL)


def test_long_trajectories_keep_every_kth_sample_and_the_last(client):
    t, q, result = _glt_motion(2 * MAX_FRAMES + 7)
    _store(client, "long", "motion", {"robot": GLT}, result)
    _, data = _page(client, "/jobs/long/replay.html")
    assert 2 <= data["frames"] <= MAX_FRAMES
    assert data["t"][0] == 0.0 and data["t"][-1] == pytest.approx(t[-1], abs=1e-6)
    tool = _poses(data, f"{GLT}/tool")
    _close(tool[-1], fk(builtin_model(GLT), q[-1]))
    stride = round(data["t"][1] / (t[1] - t[0]))
    assert stride >= 2
    _close(tool[1], fk(builtin_model(GLT), q[stride]))


# ---- an imported robot with its meshes ------------------------------------------------------
BALL_SUBDIVISIONS = 5  # 20480 triangles: more than a page holds with the rest


def _meshed_glt() -> bytes:
    """The palletizer as a URDF: link_2 a dense ball mesh (STL, m), link_3 a red box."""
    import trimesh

    text = to_urdf(builtin_model(GLT))
    ball = trimesh.creation.icosphere(subdivisions=BALL_SUBDIVISIONS, radius=0.12)
    mesh = ('<visual><geometry><mesh filename="package://glt/meshes/ball.stl"/></geometry>'
            '</visual>')
    box = ('<visual><origin xyz="0.1 0 0"/><geometry><box size="0.2 0.1 0.1"/></geometry>'
           '<material name="red"><color rgba="1 0 0 1"/></material></visual>')
    for link, body in (("link_2", mesh), ("link_3", box)):
        assert f'<link name="{link}" />' in text
        text = text.replace(f'<link name="{link}" />', f'<link name="{link}">{body}</link>')
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt/urdf/glt.urdf", text)
        z.writestr("glt/meshes/ball.stl", ball.export(file_type="stl"))
    return buf.getvalue()


@pytest.mark.slow
def test_an_imported_robot_is_drawn_with_its_meshes_at_its_link_poses(client):
    pytest.importorskip("trimesh")
    r = client.post("/robots/import", files={"file": ("glt.zip", _meshed_glt(),
                                                      "application/zip")},
                    data={"id": "glt_mesh"})
    assert r.status_code == 201, r.text
    robot = client.app.state.registry.imported("glt_mesh")
    t = np.linspace(0.0, 3.0, 31)
    q = np.outer(t, [0.3, 0.1, -0.2, 0.4, 0.2, -0.5])
    tracking = {
        "robot": "glt_mesh", "task": {"kind": "line"}, "controller": "pi", "tune": None,
        "mean_error": 0.1, "max_error": 0.2, "std_error": 0.05, "kp": [0.5, 0.5], "ki": 1.0,
        "seed": 0, "t": t.tolist(), "x_desired": [[0.0, 0.0, 0.0]] * 31,
        "x_actual": [[0.0, 0.0, 0.0]] * 31, "q": q.tolist(), "errors": [0.0] * 31,
        "joint_speed_max": 0.9, "saturated_steps": 0, "fitness_history": []}
    _store(client, "meshed", "tracking", {"robot": "glt_mesh"}, tracking)
    _, data = _page(client, "/jobs/meshed/replay.html")
    assert data["frames"] == 31 and data["robots"] == ["glt_mesh"]
    nodes = {n["name"]: n for n in data["nodes"]}
    # only the links with geometry, each shape in its link's frame
    assert data["links"] == ["glt_mesh/link_2", "glt_mesh/link_3"]
    assert set(nodes) == {"glt_mesh/link_2/visual_0", "glt_mesh/link_3/visual_0"}
    assert nodes["glt_mesh/link_3/visual_0"]["color"] == [255, 0, 0]
    box = np.reshape(nodes["glt_mesh/link_3/visual_0"]["v"], (-1, 3))
    np.testing.assert_allclose(box.min(axis=0), [0, -50, -50], atol=MM_TOL)
    np.testing.assert_allclose(box.max(axis=0), [200, 50, 50], atol=MM_TOL)
    # the dense ball, decimated to fit the page, still a ball of 120 mm
    assert 20 * 4 ** BALL_SUBDIVISIONS > MAX_TRIANGLES >= data["triangles"]
    ball = nodes["glt_mesh/link_2/visual_0"]
    assert 100 <= len(ball["f"]) // 3 < 20 * 4 ** BALL_SUBDIVISIONS
    radii = np.linalg.norm(np.reshape(ball["v"], (-1, 3)), axis=1)
    assert 100.0 < radii.min() and radii.max() <= 120.0 + MM_TOL
    poses = robot.link_poses(q)  # (31, links, 4, 4)
    names = list(robot.link_names)
    for link in ("link_2", "link_3"):
        got = _poses(data, f"glt_mesh/{link}")
        for k in (0, 12, 30):
            _close(got[k], poses[k, names.index(link)])
    (desired,) = [x for x in data["lines"] if x["name"] == "desired"]
    assert len(desired["pts"]) == 31 * 3


def test_decimate_meets_its_target_inside_the_mesh_bounds():
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=4, radius=50.0)
    V, F = np.asarray(s.vertices), np.asarray(s.faces)
    for target in (2000, 300, 40):
        V2, F2 = decimate(V, F, target)
        assert 0 < len(F2) <= target
        assert F2.min() >= 0 and F2.max() < len(V2) and len(np.unique(F2)) == len(V2)
        assert np.all(np.linalg.norm(V2, axis=1) <= 50.0 + 1e-9)
        assert not np.any((F2[:, 0] == F2[:, 1]) | (F2[:, 1] == F2[:, 2])
                          | (F2[:, 0] == F2[:, 2]))
    V3, F3 = decimate(V, F, len(F))
    assert V3 is not None and np.array_equal(F3, F)


# ---- several arms ---------------------------------------------------------------------------
def _multiarm_result(t: np.ndarray) -> dict:
    base = np.array([0.1, -1.2, 6000.0, 0.0, 1.2, 1.5, 500.0])
    arms = {}
    for k, arm in enumerate(("left", "middle", "right")):
        arms[arm] = {
            "holes": [[9000.0, 1000.0 * (k - 1), 1000.0]], "hole_ids": [f"{arm}[0]"],
            "q": (base + np.outer(t, [0.02, 0.01, 100.0, 0.0, 0.0, 0.0, 50.0]) + 0.1 * k
                  ).tolist(), "move_starts_s": [0.0], "end_s": float(t[-1]), "travel_m": 1.0,
            "sequence_length_m": 0.0, "planner_counts": {"iapf": 1},
            "peak_acceleration": [0.1] * 7, "max_rotational_acceleration": 0.1,
            "boom_time_s": 1.0, "boom_time_distance_order_s": 1.0}
    pairs = ("left-middle", "left-right", "middle-right")
    return {"rig": "tunnel_jumbo", "planner": "iapf", "success": True, "messages": [],
            "notes": [], "middle_park": "last_hole", "t": t.tolist(), "arms": arms,
            "min_distance": {p: [500.0] * len(t) for p in pairs},
            "min_distance_overall": {p: 500.0 for p in pairs}, "collisions": 0,
            "collisions_by_pair": {p: 0 for p in pairs},
            "travel_m": {a: 1.0 for a in arms}, "total_travel_m": 3.0, "cost": "distance",
            "boom_time_s": 3.0, "boom_time_distance_order_s": 3.0, "boom_time_saved_s": 0.0,
            "acceleration_bound": 0.25, "check_dt": 0.01, "samples": 100, "runtime_s": 1.0}


def test_a_multiarm_plan_shows_every_arm_or_the_one_asked(client):
    t = np.linspace(0.0, 4.0, 9)
    result = _multiarm_result(t)
    _store(client, "face", "multiarm", {"holes": {}}, result)
    _, data = _page(client, "/jobs/face/replay.html")
    rig = builtin_rig("tunnel_jumbo")
    assert data["robots"] == ["left", "middle", "right"] and data["frames"] == 9
    for arm in ("left", "middle", "right"):
        q = np.asarray(result["arms"][arm]["q"])
        _close(_poses(data, f"{arm}/tool")[4], fk(rig.arms[arm], q[4]))
    assert sorted(p["name"] for p in data["points"]) == ["left/holes", "middle/holes",
                                                        "right/holes"]
    _, one = _page(client, "/jobs/face/replay.html?arm=middle")
    assert one["robots"] == ["middle"]
    r = client.get("/jobs/face/replay.html?arm=top")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "arm"]


# ---- a path planned for a robot ------------------------------------------------------------
def test_a_path_job_shows_its_obstacles_and_bounds(client):
    t = np.linspace(0.0, 2.0, 5)
    q = np.outer(np.ones(5), GLT_START) + np.outer(t, [0.5, 0, 0, 0, 0, 0])
    trajectory = {"t": t.tolist(), "q": q.tolist(), "qd": np.zeros((5, 6)).tolist(),
                  "qdd": np.zeros((5, 6)).tolist(), "waypoints": [q[0].tolist(), q[-1].tolist()]}
    result = {"path": [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], "length": 1.7, "min_clearance": None,
              "runtime_s": 0.1, "convergence": [], "algorithm": "auto", "evaluations": 1,
              "success": True, "status": "ok", "message": "ok", "raw_length": 1.7,
              "joint_path": q.tolist(), "trajectory": trajectory, "cylinders": None,
              "robot": GLT, "planner": "tool_space", "arm_min_clearance": 10.0,
              "tool_samples": [[0.0, 0.0, 0.0]]}
    scene = {"bounds": [[-2000, -2000, 0], [2000, 2000, 2500]], "obstacles": [
        {"center": [1000, 0, 500], "radius": 150},
        {"type": "box", "lower": [-500, 800, 0], "upper": [-300, 1000, 400]},
        {"type": "capsule", "a": [0, -800, 200], "b": [0, -800, 900], "radius": 60}]}
    _store(client, "arm", "path", {"robot": GLT, "scene": scene}, result)
    _, data = _page(client, "/jobs/arm/replay.html")
    assert data["frames"] == 5 and data["robots"] == [GLT]
    _close(_poses(data, f"{GLT}/tool")[3], fk(builtin_model(GLT), q[3]))
    nodes = {n["name"]: np.reshape(n["v"], (-1, 3)) for n in data["nodes"]}
    np.testing.assert_allclose(np.linalg.norm(nodes["scene/obstacle_0"] - [1000, 0, 500],
                                              axis=1), 150.0, atol=MM_TOL)
    np.testing.assert_allclose(nodes["scene/obstacle_1"].min(axis=0), [-500, 800, 0])
    np.testing.assert_allclose(nodes["scene/obstacle_1"].max(axis=0), [-300, 1000, 400])
    np.testing.assert_allclose(nodes["scene/obstacle_2"][:, 2].max(), 960.0, atol=0.5)
    (bounds,) = [x for x in data["lines"] if x["name"] == "scene/bounds"]
    corners = np.reshape(bounds["pts"], (-1, 3))
    np.testing.assert_allclose(corners.min(axis=0), [-2000, -2000, 0])
    np.testing.assert_allclose(corners.max(axis=0), [2000, 2000, 2500])


# ---- errors ---------------------------------------------------------------------------------
def test_an_unknown_job_is_404(client):
    r = client.get("/jobs/0000000000000000/replay.html")
    assert r.status_code == 404 and _detail(r)["loc"] == ["path", "job_id"]


def test_a_job_not_succeeded_is_409_saying_its_status(client):
    _store(client, "waiting", "motion", {"robot": GLT}, None, status="queued")
    r = client.get("/jobs/waiting/replay.html")
    assert r.status_code == 409 and _detail(r)["loc"] == ["path", "job_id"]
    assert "is queued" in _detail(r)["msg"]
    _store(client, "broke", "motion", {"robot": GLT}, None, status="failed",
           error="time limit of 5 s exceeded")
    r = client.get("/jobs/broke/replay.html")
    assert r.status_code == 409 and "time limit" in _detail(r)["msg"]


@pytest.mark.slow
def test_jobs_without_a_trajectory_are_422_as_for_the_trajectory_export(client):
    _store(client, "ws", "echo", {"value": 1}, {"value": 1})
    r = client.get("/jobs/ws/replay.html")
    assert r.status_code == 422 and _detail(r)["loc"] == ["path", "job_id"]
    assert _detail(r)["msg"] == _detail(client.get("/jobs/ws/trajectory"))["msg"]
    assert all(k in _detail(r)["msg"] for k in ("motion", "path", "multiarm", "tracking"))
    _, _, result = _glt_motion(5)
    result |= {"status": "no_path", "message": "no path", "path": [], "trajectory": None}
    _store(client, "stuck", "motion", {"robot": GLT}, result)
    r = client.get("/jobs/stuck/replay.html")
    assert r.status_code == 422 and "no_path" in _detail(r)["msg"]
    _, _, result = _glt_motion(5)
    _store(client, "one", "motion", {"robot": GLT}, result)
    r = client.get("/jobs/one/replay.html?problem=1")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "problem"]


# ---- a motion answer posted back ------------------------------------------------------------
def test_a_posted_motion_answer_replays_with_its_scene(client):
    model = builtin_model(GLT)
    scene = {"objects": SCENE["objects"][:2]}
    body = {"start": GLT_START.tolist(), "goal": {"q": GLT_GOAL.tolist()}, "scene": scene,
            "time_limit": 2.0}
    answer = client.post(f"/robots/{GLT}/motion", json=body).json()
    assert answer["status"] == "ok", answer
    r = client.post(f"/robots/{GLT}/motion/replay.html", json={"answer": answer,
                                                               "scene": scene})
    assert r.status_code == 200, r.text
    assert r.headers["content-type"].startswith("text/html")
    assert not re.search(r"https?://", r.text)
    (found,) = DATA.findall(r.text)
    data = json.loads(found)
    assert data["kind"] == "motion" and data["robots"] == [GLT]
    t = np.asarray(answer["trajectory"]["t"])
    q = np.asarray(answer["trajectory"]["q"])
    assert data["frames"] == len(t)
    np.testing.assert_allclose(data["t"], t - t[0], atol=1e-6)
    for k in (0, len(q) // 2, len(q) - 1):
        _close(_poses(data, f"{GLT}/tool")[k], fk(model, q[k]))
    names = {n["name"] for n in data["nodes"]}
    assert {"scene/pallet", "scene/ball"} <= names and "scene/post" not in names
    # without a scene: the robot alone
    r = client.post(f"/robots/{GLT}/motion/replay.html", json={"answer": answer})
    (found,) = DATA.findall(r.text)
    assert not any(n["name"].startswith("scene/") for n in json.loads(found)["nodes"])


def test_a_posted_answer_that_does_not_fit_is_422_naming_the_field(client):
    t, q = [0.0, 1.0], [GLT_START.tolist(), GLT_GOAL.tolist()]
    url = f"/robots/{GLT}/motion/replay.html"

    def loc(body: dict, status: int = 422) -> list:
        r = client.post(url, json=body)
        assert r.status_code == status, r.text
        return _detail(r)["loc"]

    assert loc({"answer": {"robot": "ur5", "trajectory": {"t": t, "q": q}}}) == [
        "body", "answer", "robot"]
    assert loc({"answer": {"trajectory": {"t": t, "q": [row[:5] for row in q]}}}) == [
        "body", "answer", "trajectory", "q"]
    assert loc({"answer": {"trajectory": {"t": [1.0, 0.5], "q": q}}}) == [
        "body", "answer", "trajectory"]
    assert loc({"answer": {"trajectory": {"t": t, "q": q[:1]}}}) == [
        "body", "answer", "trajectory"]
    assert loc({"answer": {"status": "ok"}}) == ["body", "answer", "trajectory"]
    assert loc({"answer": {"trajectory": {"t": t, "q": q}}, "scene": "no-such-scene"},
               404) == ["path", "scene_id"]
    assert client.post("/robots/no-such-robot/motion/replay.html",
                       json={"answer": {"trajectory": {"t": t, "q": q}}}).status_code == 404


# ---- a drilling round: each boom on its own times ---------------------------------------------
def _round_result() -> tuple[dict, dict]:
    """Two booms of the jumbo, the left ending at 4 s, the middle at 6 s (own samples)."""
    rig = builtin_rig("tunnel_jumbo")
    booms = {}
    for name, end in (("left", 4.0), ("middle", 6.0)):
        model = rig.arms[name]
        t = np.linspace(0.0, end, int(end) + 1)
        lo, hi = np.asarray(model.lower), np.asarray(model.upper)
        a, b = lo + 0.3 * (hi - lo), lo + 0.6 * (hi - lo)
        q = a + np.outer(t / end, b - a)
        booms[name] = {"holes": [f"{name[0].upper()}1"], "priority": 0, "t": t.tolist(),
                       "q": q.tolist(), "phases": [{"kind": "transfer", "start_s": 0.0,
                                                    "end_s": end, "hole": None}],
                       "wait_s": 0.0, "end_s": end}
    holes = [{"id": "L1", "boom": "left", "start_s": 1.0, "end_s": 3.0, "depth_mm": 1000.0,
              "drill_s": 2.0},
             {"id": "M1", "boom": "middle", "start_s": 1.0, "end_s": 5.0, "depth_mm": 1000.0,
              "drill_s": 4.0}]
    result = {"rig": "tunnel_jumbo", "booms": booms, "holes": holes, "unreachable": [],
              "cycle_time_s": 6.0, "lower_bound_s": 3.0, "ratio": 2.0,
              "min_boom_clearance_mm": 500.0, "clearance_pair": "left-middle",
              "clearance_t_s": 2.0, "checked_instants": 600, "max_step_mm": 4.0,
              "priority": ["middle", "left"], "notes": [], "planning_time_s": 1.0}
    params = {"holes": [{"id": "L1", "collar": [9000, 2000, 1500], "toe": [10000, 2000, 1500]},
                        {"id": "M1", "collar": [9000, 0, 2500], "toe": [10000, 0, 2500]}]}
    return params, result


def test_a_round_plays_every_boom_on_its_own_times_and_exports_per_boom(client):
    params, result = _round_result()
    _store(client, "rnd", "round", params, result)
    rig = builtin_rig("tunnel_jumbo")
    _, data = _page(client, "/jobs/rnd/replay.html")
    assert data["robots"] == ["left", "middle"]
    np.testing.assert_allclose(data["t"], np.linspace(0.0, 6.0, 7), atol=1e-6)  # the longer
    for name in ("left", "middle"):
        boom = result["booms"][name]
        for k, t in enumerate(data["t"]):
            q = np.array([np.interp(t, boom["t"], col) for col in np.asarray(boom["q"]).T])
            _close(_poses(data, f"{name}/tool")[k], fk(rig.arms[name], q))  # held at its end
    holes = {x["name"]: np.reshape(x["pts"], (-1, 3)) for x in data["lines"]
             if x["name"].endswith("/holes")}
    np.testing.assert_allclose(holes["left/holes"], [[9000, 2000, 1500], [10000, 2000, 1500]])
    # The trajectory files: one per boom, its own samples.
    r = client.get("/jobs/rnd/trajectory?arm=middle")
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["robot"] == rig.arms["middle"].id and len(out["points"]) == 7
    np.testing.assert_allclose([p["positions"] for p in out["points"]],
                               result["booms"]["middle"]["q"], atol=1e-12)
    r = client.get("/jobs/rnd/trajectory?format=csv")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "arm"]
