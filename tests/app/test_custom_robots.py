"""Custom robots: POST/DELETE /robots, persistence in the SQLite store, validation, URDF."""

from __future__ import annotations

import copy
import json
import sqlite3
import threading
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from app.registry import RobotRegistry
from app.store import DuplicateError, Store
from kinematics.fk import fk
from kinematics.library import BUILTIN_IDS
from kinematics.model import RobotModel

MDH_SLIDE = {
    "id": "mdh_slide",
    "name": "MDH arm with a telescopic boom",
    "convention": "mdh",
    "joints": [
        {"name": "swing", "type": "revolute", "a": 0, "alpha": 0, "d": 300, "lower": -3,
         "upper": 3, "velocity": 1.0},
        {"name": "boom", "type": "revolute", "a": 150, "alpha": -np.pi / 2, "d": 0,
         "offset": -0.4, "lower": -1.5, "upper": 1.2},
        {"name": "telescope", "type": "prismatic", "a": 900, "alpha": np.pi / 2, "theta": 0.2,
         "offset": 50, "lower": 0, "upper": 800, "velocity": 200},
        {"name": "tilt", "type": "revolute", "a": 0, "alpha": -np.pi / 2, "d": 40,
         "offset": 0.3, "lower": -2, "upper": 2},
    ],
    "base": [[0, -1, 0, 100], [1, 0, 0, 0], [0, 0, 1, 20], [0, 0, 0, 1]],
    "tool": [[1, 0, 0, 10], [0, 1, 0, 0], [0, 0, 1, 60], [0, 0, 0, 1]],
    "notes": ["extra fields are kept"],
}
SDH_ARM = {
    "id": "sdh_arm",
    "convention": "sdh",
    "joints": [
        {"type": "revolute", "a": 50, "alpha": -np.pi / 2, "d": 300, "lower": -3, "upper": 3},
        {"type": "prismatic", "a": 0, "alpha": np.pi / 2, "theta": 0.3, "offset": 25,
         "lower": 0, "upper": 500},
        {"type": "revolute", "a": 120, "alpha": 0.4, "d": 10, "offset": 0.2, "lower": -2,
         "upper": 2},
    ],
    "tool": [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 75], [0, 0, 0, 1]],
}
POE_ARM = {
    "id": "poe_arm",
    "convention": "poe",
    "joints": [
        {"type": "revolute", "axis": [0, 0, 1], "point": [0, 0, 0], "lower": -3, "upper": 3},
        {"type": "revolute", "axis": [0, 1, 0], "point": [0, 0, 400], "lower": -2, "upper": 2},
        {"type": "prismatic", "axis": [1, 0, 0], "lower": 0, "upper": 300},
        {"type": "revolute", "axis": [1, 0, 0], "point": [500, 0, 400], "offset": 0.5,
         "lower": -3, "upper": 3},
    ],
    "home": [[1, 0, 0, 600], [0, 1, 0, 0], [0, 0, 1, 400], [0, 0, 0, 1]],
    "tool": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]],
}
CUSTOM = [MDH_SLIDE, SDH_ARM, POE_ARM]
CUSTOM_IDS = [m["id"] for m in CUSTOM]


def make_app(data_dir):
    """An app whose registry keeps custom robots in ``data_dir`` (until ``create_app`` wires
    the store itself, the test does)."""
    api = create_app(Settings(no_viewer=True, data_dir=data_dir))
    api.state.registry = RobotRegistry(Store.in_data_dir(data_dir))
    return api


@pytest.fixture
def client(tmp_path) -> TestClient:
    return TestClient(make_app(tmp_path))


def random_q(model: RobotModel, n: int = 8, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.lower, model.upper, (n, model.dof))


def assert_fk_matches(client: TestClient, data: dict) -> None:
    """The service's FK of the stored robot equals the library's FK of the posted model."""
    model = RobotModel.from_dict(data)
    q = random_q(model)
    r = client.post(f"/robots/{model.id}/fk", json={"q": q.tolist()})
    assert r.status_code == 200, r.text
    np.testing.assert_allclose(np.array(r.json()["poses"]), fk(model, q), rtol=0, atol=1e-9)


def error_locs(response) -> list[list]:
    return [entry["loc"] for entry in response.json()["detail"]]


# ---- create, read, list, FK --------------------------------------------------------------
@pytest.mark.parametrize("data", CUSTOM, ids=CUSTOM_IDS)
def test_create_then_list_get_and_fk(client, data):
    r = client.post("/robots", json=data)
    assert r.status_code == 201, r.text
    expected = RobotModel.from_dict(data).to_dict()
    assert r.json() == expected

    listing = {entry["id"]: entry for entry in client.get("/robots").json()}
    assert set(BUILTIN_IDS) <= set(listing)
    entry = listing[data["id"]]
    assert entry["builtin"] is False
    assert entry["dof"] == len(data["joints"])
    assert entry["convention"] == data["convention"]
    assert [j["type"] for j in entry["joints"]] == [j["type"] for j in data["joints"]]

    r = client.get(f"/robots/{data['id']}")
    assert r.status_code == 200
    assert r.json() == expected
    assert_fk_matches(client, data)


def test_extra_fields_are_kept(client):
    r = client.post("/robots", json=MDH_SLIDE)
    assert r.status_code == 201
    assert client.get("/robots/mdh_slide").json()["notes"] == MDH_SLIDE["notes"]


def test_custom_robots_persist_across_a_restart(tmp_path):
    first = TestClient(make_app(tmp_path))
    for data in CUSTOM:
        assert first.post("/robots", json=data).status_code == 201

    second = TestClient(make_app(tmp_path))
    listing = {entry["id"]: entry for entry in second.get("/robots").json()}
    for data in CUSTOM:
        assert listing[data["id"]]["builtin"] is False
        assert second.get(f"/robots/{data['id']}").json() == RobotModel.from_dict(
            data).to_dict()
        assert_fk_matches(second, data)


# ---- conflicts and deletion ---------------------------------------------------------------
def test_duplicate_id_is_409(client):
    assert client.post("/robots", json=SDH_ARM).status_code == 201
    r = client.post("/robots", json={**POE_ARM, "id": SDH_ARM["id"]})
    assert r.status_code == 409
    assert error_locs(r) == [["body", "id"]]
    # The first model is untouched.
    assert client.get("/robots/sdh_arm").json()["convention"] == "sdh"


@pytest.mark.parametrize("robot_id", BUILTIN_IDS)
def test_builtin_id_is_409(client, robot_id):
    r = client.post("/robots", json={**SDH_ARM, "id": robot_id})
    assert r.status_code == 409
    assert error_locs(r) == [["body", "id"]]
    assert client.get(f"/robots/{robot_id}").json()["convention"] != "sdh"


def test_delete_then_404_and_gone_after_restart(tmp_path):
    client = TestClient(make_app(tmp_path))
    assert client.post("/robots", json=POE_ARM).status_code == 201
    r = client.delete("/robots/poe_arm")
    assert r.status_code == 204
    assert r.content == b""
    assert client.get("/robots/poe_arm").status_code == 404
    assert client.delete("/robots/poe_arm").status_code == 404
    assert "poe_arm" not in {e["id"] for e in client.get("/robots").json()}
    restarted = TestClient(make_app(tmp_path))
    assert restarted.get("/robots/poe_arm").status_code == 404
    # The id is free again.
    assert restarted.post("/robots", json=POE_ARM).status_code == 201


def test_delete_unknown_is_404(client):
    r = client.delete("/robots/no_such_robot")
    assert r.status_code == 404
    assert error_locs(r) == [["path", "robot_id"]]


@pytest.mark.parametrize("robot_id", BUILTIN_IDS)
def test_delete_builtin_is_403(client, robot_id):
    r = client.delete(f"/robots/{robot_id}")
    assert r.status_code == 403
    assert error_locs(r) == [["path", "robot_id"]]
    assert client.get(f"/robots/{robot_id}").status_code == 200


# ---- validation ---------------------------------------------------------------------------
def _with(path: list, value):
    """A copy of MDH_SLIDE with the field at ``path`` set to ``value``."""
    data = copy.deepcopy(MDH_SLIDE)
    target = data
    for part in path[:-1]:
        target = target[part]
    target[path[-1]] = value
    return data


def _without(key: str) -> dict:
    return {k: v for k, v in MDH_SLIDE.items() if k != key}


INVALID = {
    "lower_not_below_upper": (_with(["joints", 2, "lower"], 900), ["joints", 2, "lower"]),
    "nan": (_with(["joints", 1, "upper"], float("nan")), ["joints", 1, "upper"]),
    "infinity_in_an_extra_field": (_with(["notes", 0], float("inf")), ["notes", 0]),
    "unknown_convention": (_with(["convention"], "dh"), ["convention"]),
    "non_rigid_base": (
        _with(["base"], [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]), ["base"]
    ),
    "33_joints": (
        _with(["joints"], [{"name": f"j{k}", "lower": -1, "upper": 1} for k in range(33)]),
        ["joints"],
    ),
    "unknown_joint_field": (_with(["joints", 0, "length"], 5), ["joints", 0, "length"]),
    "missing_id": (_without("id"), ["id"]),
    "bad_id": (_with(["id"], "no spaces"), ["id"]),
    "poe_axis_not_unit": (
        {**POE_ARM, "joints": [{**POE_ARM["joints"][0], "axis": [0, 0, 2]}]},
        ["joints", 0, "axis"],
    ),
    "deep_nesting": (_with(["notes"], json.loads("[" * 40 + "]" * 40)), ["notes"]),
}


@pytest.mark.parametrize("case", list(INVALID))
def test_invalid_model_is_422_naming_the_field(client, case):
    data, loc = INVALID[case]
    # json.dumps writes NaN and Infinity as the raw (non-standard) tokens clients may send.
    r = client.post("/robots", content=json.dumps(data),
                    headers={"content-type": "application/json"})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"]
    assert len(detail) == 1
    assert detail[0]["type"] == "value_error"
    assert detail[0]["loc"][: len(loc) + 1] == ["body", *loc]
    assert detail[0]["msg"]
    assert client.get(f"/robots/{data.get('id')}").status_code == 404


@pytest.mark.parametrize("body", [b"[1, 2]", b"{not json", b"", b"\xff\xfe\x00"])
def test_body_not_a_json_object_is_422(client, body):
    r = client.post("/robots", content=body, headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert error_locs(r) == [["body"]]


@pytest.mark.slow
def test_oversize_body_is_413(client):
    data = {**SDH_ARM, "id": "big", "notes": "x" * (300 * 1024)}
    r = client.post("/robots", json=data)
    assert r.status_code == 413
    assert error_locs(r) == [["body"]]
    assert client.get("/robots/big").status_code == 404


def test_oversize_body_without_content_length_is_413(client):
    def chunks():
        yield b'{"id": "big", "notes": "'
        for _ in range(300):
            yield b"x" * 1024
        yield b'"}'

    r = client.post("/robots", content=chunks(), headers={"content-type": "application/json"})
    assert r.status_code == 413


# ---- concurrency and the store ------------------------------------------------------------
def test_concurrent_posts_all_stored(tmp_path):
    client = TestClient(make_app(tmp_path))
    n = 20
    statuses: list[int] = []
    errors: list[BaseException] = []

    def post(k: int) -> None:
        try:
            data = {**(CUSTOM[k % 3]), "id": f"arm_{k:02d}"}
            statuses.append(client.post("/robots", json=data).status_code)
        except BaseException as exc:  # surfaced below: a thread's exception is otherwise lost
            errors.append(exc)

    threads = [threading.Thread(target=post, args=(k,)) for k in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert statuses == [201] * n
    expected = {f"arm_{k:02d}" for k in range(n)}
    assert expected <= {e["id"] for e in client.get("/robots").json()}
    assert {row.id for row in Store.in_data_dir(tmp_path).list_robots()} == expected


def test_store_rows_and_duplicates(tmp_path):
    store = Store.in_data_dir(tmp_path / "new" / "dir")
    assert store.path.exists()
    row = store.put_robot("a", '{"id": "a"}')
    assert store.get_robot("a") == row
    with pytest.raises(DuplicateError):
        store.put_robot("a", "{}")
    with pytest.raises(KeyError):
        store.get_robot("b")
    assert [r.id for r in store.list_robots()] == ["a"]
    assert store.delete_robot("a") and not store.delete_robot("a")
    with sqlite3.connect(store.path) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    # Opening the file again (a restart) keeps the schema and rows.
    store.put_robot("c", "{}")
    assert [r.id for r in Store(store.path).list_robots()] == ["c"]


def test_corrupt_stored_rows_are_skipped_at_start_up(tmp_path, caplog):
    store = Store.in_data_dir(tmp_path)
    good = RobotModel.from_dict(SDH_ARM)
    store.put_robot(good.id, json.dumps(good.to_dict()))
    store.put_robot("broken_json", "{not json")
    store.put_robot("broken_model", json.dumps({**SDH_ARM, "id": "broken_model",
                                                "convention": "xyz"}))
    store.put_robot("pile_driver", json.dumps({**SDH_ARM, "id": "pile_driver"}))

    registry = RobotRegistry(store)
    assert registry.ids() == [*RobotRegistry().ids(), good.id]
    assert registry.get("pile_driver").convention == "mdh"  # the built-in wins
    assert sum("skipping stored robot" in rec.getMessage() for rec in caplog.records) == 3

    api = create_app(Settings(no_viewer=True, data_dir=tmp_path))
    api.state.registry = registry
    client = TestClient(api)
    # The skipped row still holds its id until deleted.
    assert client.post("/robots", json={**SDH_ARM, "id": "broken_json"}).status_code == 409
    assert client.delete("/robots/broken_json").status_code == 204
    assert client.post("/robots", json={**SDH_ARM, "id": "broken_json"}).status_code == 201


def test_registry_without_store_keeps_robots_in_memory():
    registry = RobotRegistry()
    registry.add(RobotModel.from_dict(POE_ARM))
    assert registry.get("poe_arm").dof == 4
    assert not registry.is_builtin("poe_arm")
    registry.remove("poe_arm")
    with pytest.raises(KeyError):
        registry.get("poe_arm")


# ---- URDF ---------------------------------------------------------------------------------
@pytest.mark.parametrize("robot_id", [*BUILTIN_IDS, "poe_arm"])
def test_urdf_endpoint(client, robot_id):
    assert client.post("/robots", json=POE_ARM).status_code == 201
    r = client.get(f"/robots/{robot_id}/urdf")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("application/xml")
    root = ET.fromstring(r.content)
    assert root.tag == "robot" and root.get("name") == robot_id
    dof = len(client.get(f"/robots/{robot_id}").json()["joints"])
    moving = [j for j in root.iter("joint") if j.get("type") != "fixed"]
    assert len(moving) == dof
    assert {link.get("name") for link in root.iter("link")} >= {"base_link", "tool"}


def test_urdf_of_unknown_robot_is_404(client):
    r = client.get("/robots/no_such_robot/urdf")
    assert r.status_code == 404
    assert error_locs(r) == [["path", "robot_id"]]
