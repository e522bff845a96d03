"""Scenes, meshes and collision queries over HTTP: stored and kept across a restart, MoveIt
planning scenes converted (metres -> mm, object pose composed with the primitive's) and given
back, every object a user can get wrong answered 422 naming it, collision answers checked
against geometry placed where FK says the robot is, and path jobs that name a stored scene.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from kinematics.fk import fk, fk_frames
from kinematics.library import builtin_model

trimesh = pytest.importorskip("trimesh")


def _pose(x=0.0, y=0.0, z=0.0, yaw=0.0) -> list:
    c, s = math.cos(yaw), math.sin(yaw)
    return [[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


@pytest.fixture
def apps(tmp_path):
    made = []

    def make() -> TestClient:
        api = create_app(Settings(no_viewer=True, data_dir=tmp_path))
        made.append(api)
        return TestClient(api, base_url="http://localhost")

    yield make
    for api in made:
        api.state.compute.shutdown()


def _upload_box_mesh(client: TestClient, mesh_id: str = "crate") -> dict:
    stl = trimesh.creation.box(extents=(400, 300, 200)).export(file_type="stl")
    r = client.post("/meshes", files={"file": ("crate.stl", stl, "model/stl")},
                    data={"id": mesh_id})
    assert r.status_code == 201, r.text
    return r.json()


CELL = {
    "id": "cell", "name": "Palletizing cell",
    "objects": [
        {"type": "box", "id": "table", "size": [1200, 800, 40], "pose": _pose(1500, 0, 400)},
        {"type": "sphere", "id": "ball", "radius": 150, "pose": _pose(-1500, 0, 500)},
        {"type": "cylinder", "id": "post", "radius": 60, "height": 1500,
         "pose": _pose(-600, 900, 750)},
        {"type": "capsule", "id": "pipe", "a": [0, -1500, 200], "b": [800, -1500, 200],
         "radius": 50},
        {"type": "mesh", "id": "crate", "mesh": "crate", "pose": _pose(0, 1500, 100, 0.3)},
        {"type": "points", "id": "scan", "radius": 20,
         "points": [[2000 + 10 * i, -800, 100 + 5 * j] for i in range(20) for j in range(10)]},
    ],
}


def test_scenes_and_meshes_are_stored_and_kept(apps):
    client = apps()
    info = _upload_box_mesh(client)
    assert info["triangles"] == 12 and info["vertices"] == 8
    assert np.allclose(info["bounds"], [[-200, -150, -100], [200, 150, 100]])
    r = client.post("/scenes", json=CELL)
    assert r.status_code == 201, r.text
    stored = r.json()
    assert [o["id"] for o in stored["objects"]] == [o["id"] for o in CELL["objects"]]
    assert stored["objects"][0]["size"] == [1200, 800, 40]
    assert client.get("/scenes").json()[0]["objects"] == len(CELL["objects"])
    assert client.post("/scenes", json=CELL).status_code == 409

    # A mesh a scene uses cannot go; the restart keeps both.
    assert client.delete("/meshes/crate").status_code == 409
    client2 = apps()
    assert client2.get("/scenes/cell").json() == client.get("/scenes/cell").json()
    assert client2.get("/meshes/crate").json()["triangles"] == 12
    assert client2.delete("/scenes/cell").status_code == 204
    assert client2.get("/scenes/cell").status_code == 404
    assert client2.delete("/meshes/crate").status_code == 204
    assert client2.get("/meshes").json() == []


def test_moveit_scene_is_converted_and_given_back(apps):
    client = apps()
    # An object at (1, 0, 0.5) m turned 90 deg about z, holding a box 0.2 m along its x:
    # the box's centre is (1, 0.2, 0.5) m in the world, its x axis along the world's y.
    q = [0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)]
    moveit = {"name": "mbm", "world": {"collision_objects": [{
        "id": "shelf", "header": {"frame_id": "world"},
        "pose": {"position": {"x": 1.0, "y": 0.0, "z": 0.5},
                 "orientation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]}},
        "primitives": [{"type": "box", "dimensions": [0.3, 0.1, 0.02]},
                       {"type": "cylinder", "dimensions": [0.4, 0.05]}],
        "primitive_poses": [
            {"position": {"x": 0.2, "y": 0.0, "z": 0.0},
             "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
            {"position": {"x": 0.0, "y": 0.0, "z": 0.1},
             "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}],
    }]}}
    r = client.post("/scenes", json={"id": "mbm", "moveit": moveit})
    assert r.status_code == 201, r.text
    box, cyl = r.json()["objects"]
    assert box["type"] == "box" and np.allclose(box["size"], [300, 100, 20])
    T = np.asarray(box["pose"])
    assert np.allclose(T[:3, 3], [1000, 200, 500], atol=1e-9)
    assert np.allclose(T[:3, 0], [0, 1, 0], atol=1e-12)
    assert cyl["type"] == "cylinder" and np.isclose(cyl["height"], 400)
    assert np.isclose(cyl["radius"], 50)
    assert np.allclose(np.asarray(cyl["pose"])[:3, 3], [1000, 0, 600], atol=1e-9)

    back = client.get("/scenes/mbm?format=moveit")
    assert back.status_code == 200
    r2 = client.post("/scenes", json={"id": "mbm2", "moveit": back.json()})
    assert r2.status_code == 201, r2.text
    for a, b in zip(r.json()["objects"], r2.json()["objects"]):
        assert a["type"] == b["type"]
        assert np.allclose(a["pose"], b["pose"], atol=1e-9)


@pytest.mark.parametrize("obj, loc, words", [
    ({"type": "sphere", "radius": -5}, ["objects", 0, "radius"], "positive"),
    ({"type": "cone", "radius": 5}, ["objects", 0, "type"], "box"),
    ({"type": "box", "size": [1, 1, 1],
      "pose": [[1, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
     ["objects", 0, "pose"], "rigid"),
    ({"type": "mesh", "mesh": "nothing_here"}, ["objects", 0, "mesh"], "nothing_here"),
    ({"type": "box"}, ["objects", 0, "size"], "size"),
])
def test_bad_objects_are_named(apps, obj, loc, words):
    client = apps()
    r = client.post("/scenes", json={"id": "bad", "objects": [obj]})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", *loc]
    assert words in detail["msg"]
    assert client.get("/scenes/bad").status_code == 404


@pytest.mark.slow
def test_bad_scene_bodies(apps):
    client = apps()
    r = client.post("/scenes", json={"objects": []})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "id"]
    r = client.post("/scenes", json={"id": "x", "objects": [], "extra": 1})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "extra"]
    r = client.post("/scenes", content=b'{"id": "x", "objects": [{"type": "sphere", '
                    b'"radius": NaN}]}', headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "objects", 0, "radius"]
    r = client.post("/meshes", files={"file": ("junk.stl", b"not a mesh " * 50, "model/stl")},
                    data={"id": "junk"})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][:2] == ["body", "file"]
    cloud = [[float(i), 0.0, 0.0] for i in range(200_001)]
    r = client.post("/scenes", json={"id": "big", "objects": [
        {"type": "points", "radius": 5, "points": cloud}]})
    assert r.status_code in (413, 422), r.text


def test_collision_answers_follow_the_geometry(apps):
    client = apps()
    model = builtin_model("glt_palletizer")
    q = model.mid_configuration()
    tool = fk(model, q)[:3, 3]
    frames = fk_frames(model, q)[:, :3, 3]
    far = tool + np.array([0.0, 0.0, 5000.0])
    scene = {"id": "probe", "objects": [
        {"type": "sphere", "id": "at_tool", "radius": 30, "pose": _pose(*tool)},
    ]}
    assert client.post("/scenes", json=scene).status_code == 201
    r = client.post("/robots/glt_palletizer/collision", json={"q": q.tolist(), "scene": "probe"})
    assert r.status_code == 200, r.text
    (hit,) = r.json()["results"]
    assert hit["collides"] is True and hit["distance"] <= 0
    assert hit["pairs"] and hit["pairs"][0]["object"] == "at_tool"

    # The same robot with the ball far above its tool: free, and the distance (a lower bound
    # of the true clearance) is at most the distance from the ball to the nearest frame.
    inline = {"objects": [{"type": "sphere", "id": "far", "radius": 30, "pose": _pose(*far)}]}
    r = client.post("/robots/glt_palletizer/collision", json={"q": q.tolist(), "scene": inline})
    (free,) = r.json()["results"]
    assert free["collides"] is False
    upper = float(np.min(np.linalg.norm(frames - far, axis=1))) - 30
    assert 0 < free["distance"] <= upper
    r = client.post("/robots/glt_palletizer/collision",
                    json={"q": q.tolist(), "scene": inline, "exact_distance": True})
    exact = r.json()["results"][0]
    assert exact["distance_exact"] is True
    assert free["distance"] - 1e-6 <= exact["distance"] <= upper + 1e-6

    # A batch answers as the single queries did.
    r = client.post("/robots/glt_palletizer/collision",
                    json={"q": [q.tolist(), q.tolist()], "scene": "probe", "self": False})
    assert [x["collides"] for x in r.json()["results"]] == [True, True]

    # Errors name the field.
    r = client.post("/robots/glt_palletizer/collision", json={"q": [0, 0], "scene": "probe"})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "q"]
    r = client.post("/robots/glt_palletizer/collision", json={"q": q.tolist(), "scene": "nope"})
    assert r.status_code == 404
    r = client.post("/robots/glt_palletizer/collision",
                    json={"q": q.tolist(), "scene": {"objects": [{"type": "sphere"}]}})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"][:4] == ["body", "scene", "objects", 0]

    r = client.post("/robots/glt_palletizer/collision",
                    json={"q": [q.tolist()] * 1_001, "scene": "probe"})
    assert r.status_code == 413 and r.json()["detail"][0]["loc"][:2] == ["body", "q"]

    described = client.get("/robots/glt_palletizer/collision").json()
    assert described["links"] and all(link["spheres"] > 0 for link in described["links"])


def _wait(client: TestClient, job_id: str, timeout_s: float = 120.0) -> dict:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in ("succeeded", "failed", "cancelled"):
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not end")


@pytest.mark.slow
def test_a_path_job_names_a_stored_scene(apps):
    client = apps()
    with client:
        scene = {"id": "hall", "objects": [
            {"type": "box", "id": "wall", "size": [200, 2000, 2000],
             "pose": _pose(0, 0, 1000, 0.2)},
            {"type": "cylinder", "id": "column", "radius": 100, "height": 2000,
             "pose": _pose(600, 600, 1000)},
        ]}
        assert client.post("/scenes", json=scene).status_code == 201
        r = client.post("/jobs", json={"kind": "path", "params": {
            "scene": "hall", "start": [-1000, 0, 1000], "goal": [1000, 0, 1000]}})
        assert r.status_code in (200, 201, 202), r.text
        job = r.json()
        # The job records the obstacles it used: the box's bounding box, the cylinder as a
        # capsule along its axis.
        obstacles = job["params"]["scene"]["obstacles"]
        assert job["params"]["scene"]["id"] == "hall"
        assert [o["type"] for o in obstacles] == ["box", "capsule"]
        half_x = 0.5 * (200 * math.cos(0.2) + 2000 * math.sin(0.2))
        assert np.isclose(obstacles[0]["upper"][0], half_x)
        assert np.allclose(obstacles[1]["a"], [600, 600, 0])
        assert np.allclose(obstacles[1]["b"], [600, 600, 2000])
        done = _wait(client, job["id"])
        assert done["status"] == "succeeded", done
        r = client.post("/jobs", json={"kind": "path", "params": {
            "scene": "nowhere", "start": [0, 0, 0], "goal": [1, 1, 1]}})
        assert r.status_code == 404
        assert r.json()["detail"][0]["loc"][-1] == "id"
