"""POST /robots/import over HTTP: a URDF with meshes in a zip, its SRDF, the stored robot served
by every endpoint, kept across a restart, exported and imported again; every upload a user can
get wrong answers 422 naming the field and the URDF element.

The fixture is made here: the GLT palletizer written as URDF by ``to_urdf`` with trimesh box
and cylinder meshes attached to two links through ``package://`` paths. FK through the API is
checked against yourdfpy reading the same file (an independent URDF reader).
"""

from __future__ import annotations

import io
import json
import logging
import zipfile

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from kinematics.library import builtin_model
from kinematics.urdf import to_urdf

trimesh = pytest.importorskip("trimesh")
yourdfpy = pytest.importorskip("yourdfpy")
logging.getLogger("yourdfpy").setLevel(logging.ERROR)
logging.getLogger("trimesh").setLevel(logging.ERROR)

MESHED = {"link_2": "upper_arm.stl", "link_3": "forearm.stl"}
SRDF = """<?xml version="1.0"?>
<robot name="glt_palletizer">
  <group name="arm"><chain base_link="base_link" tip_link="tool"/></group>
  <disable_collisions link1="link_1" link2="link_3" reason="Never"/>
</robot>
"""


def _urdf() -> str:
    text = to_urdf(builtin_model("glt_palletizer"))
    for link, mesh in MESHED.items():
        text = text.replace(
            f'<link name="{link}" />',
            f'<link name="{link}"><collision><geometry>'
            f'<mesh filename="package://glt_description/meshes/{mesh}"/></geometry>'
            f'</collision><visual><geometry>'
            f'<mesh filename="package://glt_description/meshes/{mesh}"/></geometry>'
            f'</visual></link>')
    return text


def _mesh_bytes(name: str) -> bytes:
    shape = (trimesh.creation.box(extents=(0.6, 0.12, 0.12)) if "upper" in name
             else trimesh.creation.cylinder(radius=0.05, height=0.5))
    return shape.export(file_type="stl")


def _archive(urdf: str | None = None, *, skip: str | None = None, extra: dict | None = None
             ) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt_description/urdf/glt.urdf", urdf or _urdf())
        for mesh in MESHED.values():
            if mesh != skip:
                z.writestr(f"glt_description/meshes/{mesh}", _mesh_bytes(mesh))
        for name, data in (extra or {}).items():
            z.writestr(name, data)
    return buf.getvalue()


def _import(client: TestClient, robot_id: str, data: bytes, filename: str = "glt.zip",
            **fields):
    files = {"file": (filename, data, "application/zip")}
    if "srdf" in fields:
        files["srdf"] = ("glt.srdf", fields.pop("srdf"), "application/xml")
    return client.post("/robots/import", files=files, data={"id": robot_id, **fields})


@pytest.fixture
def app_dir(tmp_path):
    apps = []

    def make(prebuild: bool = False) -> TestClient:
        api = create_app(Settings(no_viewer=True, data_dir=tmp_path,
                                  prebuild_collision=prebuild))
        apps.append(api)
        return TestClient(api)

    yield make
    for api in apps:
        api.state.compute.shutdown()


def _reference_fk(urdf: str, q: np.ndarray, names: list[str]) -> np.ndarray:
    """Tool poses (mm) by yourdfpy from the URDF text, one configuration at a time."""
    robot = yourdfpy.URDF.load(io.StringIO(urdf), load_meshes=False, build_scene_graph=True,
                               load_collision_meshes=False)
    out = np.empty((len(q), 4, 4))
    for k, row in enumerate(q):
        robot.update_cfg(dict(zip(names, row)))
        T = robot.get_transform("tool", robot.base_link)
        out[k] = T
        out[k, :3, 3] *= 1000.0
    return out


@pytest.mark.slow
def test_import_serves_stores_and_exports_the_robot(app_dir):
    client = app_dir()
    r = _import(client, "glt_urdf", _archive(), srdf=SRDF.encode(), name="GLT from URDF")
    assert r.status_code == 201, r.text
    model = r.json()
    names = [j["name"] for j in model["joints"]]
    assert names == [j.name for j in builtin_model("glt_palletizer").joints]
    assert model["name"] == "GLT from URDF"
    # The stored robot is the model answered (the answer adds its collision model's state).
    assert model.pop("collision_model")["state"] == "on_first_use"
    assert client.get("/robots/glt_urdf").json() == model
    assert "glt_urdf" in [r["id"] for r in client.get("/robots").json()]

    # FK through the API equals an independent URDF reader's on random configurations.
    rng = np.random.default_rng(20261130)
    lo = np.array([j["lower"] for j in model["joints"]])
    hi = np.array([j["upper"] for j in model["joints"]])
    q = rng.uniform(lo, hi, size=(40, len(lo)))
    poses = np.array(client.post("/robots/glt_urdf/fk", json={"q": q.tolist()}).json()["poses"])
    ref = _reference_fk(_urdf(), q, names)
    assert np.abs(poses - ref).max() < 1e-6  # JSON carries ~16 digits of mm values

    # Every kinematics endpoint takes it.
    assert client.post("/robots/glt_urdf/jacobian", json={"q": q[0].tolist()}).status_code == 200
    ik = client.post("/robots/glt_urdf/ik", json={"pose": poses[0].tolist(),
                                                  "method": "numeric"})
    assert ik.status_code == 200, ik.text
    assert ik.json()["results"][0]["success"] is True
    ws = client.post("/robots/glt_urdf/workspace", json={"samples": 2000, "seed": 5,
                                                         "return_points": 10})
    assert ws.status_code == 200 and ws.json()["samples"] == 2000
    traj = client.post("/trajectories", json={
        "method": "quintic", "robot": "glt_urdf", "durations": [2.0], "dt": 0.1,
        "waypoints": [q[0].tolist(), q[1].tolist()]})
    assert traj.status_code == 200, traj.text
    assert np.allclose(traj.json()["q"][-1], q[1])

    # The export names the meshes and imports again to the same FK.
    urdf = client.get("/robots/glt_urdf/urdf")
    assert urdf.status_code == 200 and "<mesh" in urdf.text
    archive = client.get("/robots/glt_urdf/archive")
    assert archive.headers["content-type"] == "application/zip"
    r2 = _import(client, "glt_again", archive.content)
    assert r2.status_code == 201, r2.text
    again = np.array(client.post("/robots/glt_again/fk", json={"q": q.tolist()}).json()["poses"])
    assert np.abs(again - poses).max() < 1e-6

    # A restart keeps both, meshes included.
    client2 = app_dir()
    assert client2.get("/robots/glt_urdf").json() == model
    after = np.array(client2.post("/robots/glt_urdf/fk", json={"q": q.tolist()}).json()["poses"])
    assert np.array_equal(after, poses)
    assert client2.get("/robots/glt_urdf/urdf").text == urdf.text
    registry = client2.app.state.registry
    robot = registry.imported("glt_urdf")
    assert robot is not None and len(robot.meshes) == 2
    assert frozenset({"link_1", "link_3"}) in robot.disabled_pairs

    # Deleting it deletes its meshes.
    assert client2.delete("/robots/glt_urdf").status_code == 204
    assert client2.app.state.store.robot_meshes("glt_urdf") == {}
    assert client2.get("/robots/glt_urdf").status_code == 404


@pytest.mark.slow
def test_the_collision_model_is_built_at_import_and_stored(app_dir):
    client = app_dir(prebuild=True)
    with client:  # the lifespan runs: the build is a task on the service's loop
        r = _import(client, "glt_cm", _archive(), srdf=SRDF.encode())
        assert r.status_code == 201
        # The answer says a build is under way, and how to wait for it.
        assert r.json()["collision_model"]["state"] == "building"
        assert "GET /robots/glt_cm/collision" in r.json()["collision_model"]["message"]
        described = client.get("/robots/glt_cm/collision")  # waits for the build if needed
        assert described.status_code == 200
        links = {link["name"]: link for link in described.json()["links"]}
        assert links["link_2"]["spheres"] > 0 and links["link_3"]["spheres"] > 0
        assert ["link_1", "link_3"] not in described.json()["self_collision_pairs"]
        store = client.app.state.store
        assert store.robot_file("glt_cm", "collision.model") is not None
    # A restart loads the stored model instead of building it again.
    client2 = app_dir()
    registry = client2.app.state.registry
    entry = registry.stored_collision("glt_cm")
    assert entry is not None
    assert entry[0].describe() == described.json()
    assert "collision.model" not in registry.imported("glt_cm").meshes


def test_a_bare_urdf_without_meshes_imports(client):
    text = to_urdf(builtin_model("pile_driver"))
    r = client.post("/robots/import", files={"file": ("pd.urdf", text.encode(), "text/xml")},
                    data={"id": "pd_urdf"})
    assert r.status_code == 201, r.text
    assert r.json()["collision_model"]["state"] == "none"  # no <collision> to build from
    assert client.get("/robots/pd_urdf/archive").status_code == 200


def test_the_import_answer_says_when_the_collision_model_is_built(client):
    r = _import(client, "glt_later", _archive())
    assert r.status_code == 201, r.text
    said = r.json()["collision_model"]
    assert said["state"] == "on_first_use"  # this app does not build at import
    assert "GET /robots/glt_later/collision" in said["message"]


def _error(r) -> tuple[list, str]:
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    return detail["loc"], detail["msg"]


@pytest.mark.slow
def test_missing_mesh_names_the_link_and_file(client):
    loc, msg = _error(_import(client, "x", _archive(skip="forearm.stl")))
    assert loc[:2] == ["body", "file"]
    assert any("link_3" in str(part) for part in loc) or "link_3" in msg
    assert "forearm.stl" in msg


@pytest.mark.slow
def test_unknown_tip_link_lists_the_candidates(client):
    loc, msg = _error(_import(client, "x", _archive(), tip_link="no_such_link"))
    assert loc == ["body", "tip_link"]
    assert "no_such_link" in msg and "tool" in msg


@pytest.mark.slow
def test_two_urdfs_need_the_urdf_field(client):
    data = _archive(extra={"glt_description/urdf/copy.urdf": _urdf()})
    loc, msg = _error(_import(client, "x", data))
    assert loc == ["body", "urdf"]
    assert "copy.urdf" in msg and "glt.urdf" in msg
    r = _import(client, "x", data, urdf="glt_description/urdf/copy.urdf")
    assert r.status_code == 201, r.text


@pytest.mark.slow
def test_a_mesh_that_is_not_a_mesh(client):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("glt_description/urdf/glt.urdf", _urdf())
        z.writestr("glt_description/meshes/upper_arm.stl", b"this is no mesh at all " * 10)
        z.writestr("glt_description/meshes/forearm.stl", _mesh_bytes("forearm.stl"))
    loc, msg = _error(_import(client, "x", buf.getvalue()))
    assert loc[:2] == ["body", "file"]
    assert "upper_arm.stl" in msg or any("upper_arm" in str(p) for p in loc)


@pytest.mark.slow
def test_a_floating_joint_on_the_chain_and_a_cycle(client):
    text = _urdf().replace('<joint name="elbow" type="revolute">',
                           '<joint name="elbow" type="floating">')
    loc, msg = _error(_import(client, "x", _archive(text)))
    assert "joint[elbow]" in loc or "elbow" in msg
    cyclic = _urdf().replace("</robot>", '<joint name="loop" type="fixed"><parent link="tool"/>'
                             '<child link="link_1"/></joint></robot>')
    loc, msg = _error(_import(client, "x", _archive(cyclic)))
    assert "link_1" in msg or any("link_1" in str(p) for p in loc)


@pytest.mark.slow
def test_bad_fields_and_conflicts(client):
    loc, _ = _error(_import(client, "x", _archive(), fixed_joints="{not json"))
    assert loc == ["body", "fixed_joints"]
    loc, _ = _error(_import(client, "bad id!", _archive()))
    assert loc == ["body", "id"]
    r = client.post("/robots/import", data={"id": "x"},
                    headers={"content-type": "multipart/form-data; boundary=zz"})
    assert r.status_code == 400 and r.json()["detail"][0]["msg"]  # not multipart at all
    r = client.post("/robots/import", data={"id": "x"}, files={"srdf": ("a.srdf", b"<robot/>")})
    assert _error(r)[0] == ["body", "file"]
    assert _import(client, "glt_palletizer", _archive()).status_code == 409
    assert _import(client, "mine", _archive()).status_code == 201
    assert _import(client, "mine", _archive()).status_code == 409
    # JSON is not an upload.
    r = client.post("/robots/import", json={"id": "y"})
    assert r.status_code == 422


def test_upload_size_is_capped(client):
    big = b"0" * (73 * 1024 * 1024)
    r = client.post("/robots/import", files={"file": ("big.zip", big, "application/zip")},
                    data={"id": "big"})
    assert r.status_code == 413


@pytest.mark.slow
def test_srdf_group_gives_the_chain(client):
    r = _import(client, "grp", _archive(), srdf=SRDF.encode(), group="arm")
    assert r.status_code == 201, r.text
    loc, msg = _error(_import(client, "grp2", _archive(), srdf=SRDF.encode(), group="nope"))
    assert loc[-1] == "group" and "arm" in msg
    fixed = json.dumps({"nothing": 1.0})
    loc, _ = _error(_import(client, "grp3", _archive(), fixed_joints=fixed))
    assert loc[:2] == ["body", "fixed_joints"]
