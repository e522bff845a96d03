"""GET /health, the robot listing and model endpoints, and the OpenAPI document."""

from __future__ import annotations

import pytest

BUILTINS = {"pile_driver": 6, "glt_palletizer": 6, "hyper_redundant_9dof": 9}


def _names_field(detail: list[dict], field: str) -> bool:
    return any(field in entry.get("loc", []) for entry in detail)


def test_health(ro_client):
    r = ro_client.get("/health")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok"
    assert isinstance(body["version"], str) and body["version"]
    assert body["jobs_backend"] == "local"


def test_list_robots_has_the_builtins(ro_client):
    r = ro_client.get("/robots")
    assert r.status_code == 200
    robots = {entry["id"]: entry for entry in r.json()}
    assert set(BUILTINS) <= set(robots)
    for robot_id, dof in BUILTINS.items():
        entry = robots[robot_id]
        assert entry["dof"] == dof
        assert entry["builtin"] is True
        assert isinstance(entry["name"], str) and entry["name"]
        assert len(entry["joints"]) == dof
        for joint in entry["joints"]:
            assert {"name", "type", "lower", "upper"} <= set(joint)
            assert isinstance(joint["name"], str)
            assert joint["type"] in ("revolute", "prismatic")
            assert joint["lower"] < joint["upper"]


@pytest.mark.parametrize("robot_id", sorted(BUILTINS))
def test_get_robot_model(ro_client, robot_id):
    r = ro_client.get(f"/robots/{robot_id}")
    assert r.status_code == 200
    model = r.json()
    assert {"convention", "joints", "base", "tool"} <= set(model)
    assert model["convention"] in ("mdh", "sdh", "poe")
    assert len(model["joints"]) == BUILTINS[robot_id]
    for key in ("base", "tool"):
        assert len(model[key]) == 4 and all(len(row) == 4 for row in model[key])
        assert model[key][3] == [0, 0, 0, 1]


def test_unknown_robot_get_is_404(ro_client):
    r = ro_client.get("/robots/no_such_robot")
    assert r.status_code == 404
    assert _names_field(r.json()["detail"], "robot_id")


def test_unknown_robot_fk_is_404(ro_client):
    r = ro_client.post("/robots/no_such_robot/fk", json={"q": [0.0] * 6})
    assert r.status_code == 404
    assert _names_field(r.json()["detail"], "robot_id")


def test_openapi_lists_the_paths(ro_client):
    r = ro_client.get("/openapi.json")
    assert r.status_code == 200
    doc = r.json()
    assert doc["info"]["title"]
    paths = doc["paths"]
    for path, method in [
        ("/health", "get"),
        ("/robots", "get"),
        ("/robots/{robot_id}", "get"),
        ("/robots/{robot_id}/fk", "post"),
        ("/robots/{robot_id}/jacobian", "post"),
        ("/robots/{robot_id}/ik", "post"),
        ("/robots/{robot_id}/workspace", "post"),
        ("/viewer/show", "post"),
    ]:
        assert path in paths, path
        assert method in paths[path], (path, method)
