"""The cylinder endpoints: POST /robots/{id}/cylinders, /cylinders/inverse, /pose-to-cylinders.

The router is included here if app.main does not register it yet, so these tests hold before
and after it does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.api.routes import cylinders
from app.config import Settings
from app.main import create_app
from kinematics.cylinders import cylinder_set
from kinematics.fk import fk
from kinematics.library import builtin_model

PILE = "/robots/pile_driver"
MODEL = builtin_model("pile_driver")
CYL = cylinder_set(MODEL)
NAMES = ["boom", "stick", "four_bar", "swing_left", "swing_right"]
Q = [0.3, 0.5, -0.4, -0.6, 0.2, -1.0]

# Section 4.5's arm scene (mm) and our reachable stand-in for its start (same bearing, 1565
# mm from the base axis instead of 1118; see tests/kinematics/test_cylinders.py).
SCENE_START = [500.0, -1000.0, 0.0]
SCENE_GOAL = [1800.0, 1800.0, 800.0]
NEAR_START_Q = [math.atan2(-1400, 700), 0.6414, -0.9926, -1.0077, 0.1, 0.2]


def _cylinder_routers(api) -> int:
    """How often the cylinder routes are registered: FastAPI >= 0.120 keeps an included
    router as one entry (``original_router``), older versions copy its routes (``path``)."""
    return sum(
        getattr(r, "original_router", None) is cylinders.router
        or getattr(r, "path", "") == "/robots/{robot_id}/cylinders"
        for r in api.routes
    )


@pytest.fixture(scope="module")
def client(tmp_path_factory) -> TestClient:
    """One app for the module: its tests only compute (like ``ro_client``)."""
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("cylinders")))
    if not _cylinder_routers(api):
        api.include_router(cylinders.router)
    return TestClient(api)


def _locs(r) -> list[list]:
    return [entry["loc"] for entry in r.json()["detail"]]


def _pose(q, position=None) -> list:
    T = fk(MODEL, np.asarray(q, dtype=float))
    if position is not None:
        T[:3, 3] = position
    return T.tolist()


def test_router_registered_once(client):
    assert _cylinder_routers(client.app) == 1


# ---------------------------------------------------------------------------------------
# POST /robots/{id}/cylinders


def test_lengths_at_a_configuration(client):
    r = client.post(f"{PILE}/cylinders", json={"q": Q})
    assert r.status_code == 200, r.text
    body = r.json()
    assert [c["name"] for c in body["cylinders"]] == NAMES
    assert [c["joint"] for c in body["cylinders"]] == ["boom", "stick", "four_bar", "tilt", "tilt"]
    expected = CYL.lengths(np.array(Q))
    for c in body["cylinders"]:
        assert c["length"] == pytest.approx(float(expected[c["name"]]), rel=1e-12)
        assert c["stroke"] == pytest.approx(c["length"] - c["min_length"], abs=1e-9)
        assert c["within_limits"] is True and "speed" not in c
    assert body["joints_within_limits"] is True


def test_speeds_with_joint_speeds(client):
    qd = [0.0, 0.1, -0.2, 0.05, 0.3, 0.0]
    r = client.post(f"{PILE}/cylinders", json={"q": Q, "qd": qd})
    assert r.status_code == 200, r.text
    cyl = {c["name"]: c for c in r.json()["cylinders"]}
    expected = CYL.speeds(np.array(Q), np.array(qd))
    for name in NAMES:
        assert cyl[name]["speed"] == pytest.approx(float(expected[name]), rel=1e-12)
    assert cyl["swing_left"]["speed"] == pytest.approx(-cyl["swing_right"]["speed"], rel=0.2)


def test_a_joint_beyond_its_limit_flags_the_cylinder(client):
    q = [0.0, -0.2, -0.5, -0.5, 0.0, 0.0]  # boom below 0: boom cylinder below its stroke
    cyl = {c["name"]: c for c in client.post(f"{PILE}/cylinders", json={"q": q}).json()[
        "cylinders"]}
    assert cyl["boom"]["within_limits"] is False and cyl["boom"]["stroke"] < 0
    assert cyl["stick"]["within_limits"] is True


@pytest.mark.parametrize(
    "body, loc",
    [
        ({"q": [0.0] * 5}, ["body", "q"]),
        ({"q": Q, "qd": [0.0] * 7}, ["body", "qd"]),
        ({"q": Q[:-1] + ["nan"]}, ["body", "q", 5]),
        ({"q": Q, "speed": 1}, ["body", "speed"]),
    ],
)
def test_lengths_bad_input_is_422(client, body, loc):
    r = client.post(f"{PILE}/cylinders", json=body)
    assert r.status_code == 422 and loc in _locs(r), r.text


def test_robot_without_cylinders_is_409(client):
    r = client.post("/robots/glt_palletizer/cylinders", json={"q": [0.0] * 6})
    assert r.status_code == 409
    assert "has no hydraulic cylinders" in r.json()["detail"][0]["msg"]
    r = client.post("/robots/glt_palletizer/cylinders/inverse", json={"lengths": {"boom": 1}})
    assert r.status_code == 409
    r = client.post("/robots/glt_palletizer/pose-to-cylinders", json={"pose": np.eye(4).tolist()})
    assert r.status_code == 409
    assert client.post("/robots/nope/cylinders", json={"q": [0.0]}).status_code == 404


# ---------------------------------------------------------------------------------------
# POST /robots/{id}/cylinders/inverse


def test_inverse_round_trip(client):
    lengths = {name: float(v) for name, v in CYL.lengths(np.array(Q)).items()}
    r = client.post(f"{PILE}/cylinders/inverse", json={"lengths": lengths, "q": Q})
    assert r.status_code == 200, r.text
    np.testing.assert_allclose(r.json()["q"], Q, atol=1e-9)
    # Joints without a cylinder default to 0; cylinders not given keep q's joint (0 here).
    only = {"boom": lengths["boom"], "swing_right": lengths["swing_right"]}
    body = client.post(f"{PILE}/cylinders/inverse", json={"lengths": only}).json()
    np.testing.assert_allclose(body["q"], [0.0, Q[1], 0.0, 0.0, Q[4], 0.0], atol=1e-9)
    assert body["joints_within_limits"] is True
    assert {c["name"]: c["length"] for c in body["cylinders"]}["boom"] == pytest.approx(
        lengths["boom"])


def test_inverse_at_the_stroke_ends_gives_the_joint_limits(client):
    lo, hi = CYL.limits("stick")
    for L, expected in ((lo, MODEL.lower[2]), (hi, MODEL.upper[2])):
        q = client.post(f"{PILE}/cylinders/inverse", json={"lengths": {"stick": L}}).json()["q"]
        assert q[2] == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize(
    "body, loc, words",
    [
        ({"lengths": {"boom": 700.0}}, ["body", "lengths", "boom"], "outside the stroke"),
        ({"lengths": {"four_bar": 300.0}}, ["body", "lengths", "four_bar"], "outside the stroke"),
        ({"lengths": {"bucket": 400.0}}, ["body", "lengths", "bucket"], "no cylinder 'bucket'"),
        ({"lengths": {"swing_left": 330.0, "swing_right": 330.0}},
         ["body", "lengths", "swing_right"], "disagrees"),
        ({"lengths": {"boom": 450.0}, "q": [0.0] * 4}, ["body", "q"], "expected 6"),
        ({"lengths": {}}, ["body", "lengths"], ""),
    ],
)
def test_inverse_errors_name_the_field(client, body, loc, words):
    r = client.post(f"{PILE}/cylinders/inverse", json=body)
    assert r.status_code == 422, r.text
    assert loc in _locs(r)
    assert words in r.json()["detail"][0]["msg"]


# ---------------------------------------------------------------------------------------
# POST /robots/{id}/pose-to-cylinders


def test_pose_to_cylinders_reachable(client):
    r = client.post(f"{PILE}/pose-to-cylinders", json={"pose": _pose(Q), "q0": Q})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["success"] is True and body["ik"]["status"] == "ok"
    np.testing.assert_allclose(body["q"], Q, atol=1e-9)
    assert body["ik"]["position_error"] < 1e-6
    assert [c["name"] for c in body["cylinders"]] == NAMES
    assert all(c["within_limits"] for c in body["cylinders"])


def test_pose_to_cylinders_near_scene_start(client):
    r = client.post(f"{PILE}/pose-to-cylinders", json={"pose": _pose(NEAR_START_Q)})
    body = r.json()
    assert r.status_code == 200 and body["success"] is True, r.text
    T = fk(MODEL, np.array(body["q"]))
    np.testing.assert_allclose(T[:3, 3], [700.0, -1400.0, 0.0], atol=0.5)
    assert all(c["within_limits"] for c in body["cylinders"])


def test_pose_to_cylinders_scene_start_is_out_of_limits(client):
    r = client.post(
        f"{PILE}/pose-to-cylinders", json={"pose": _pose(NEAR_START_Q, SCENE_START)}
    )
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["success"] is False and body["q"] is None and body["cylinders"] is None
    assert body["ik"]["status"] == "out_of_limits"
    msg = body["message"]
    assert "reachable only outside the joint limits" in msg
    # The message names the joint limits and the cylinders the nearest solution would need.
    assert "joint 'stick' needs" in msg and "limits -60.0 .. 0.0 deg" in msg
    assert "cylinder '" in msg


def test_pose_to_cylinders_scene_goal_is_unreachable(client):
    r = client.post(f"{PILE}/pose-to-cylinders", json={"pose": _pose(Q, SCENE_GOAL)})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["success"] is False and body["ik"]["status"] == "unreachable"
    assert body["message"].startswith("no cylinder lengths: unreachable:")
    assert "mm from the boom pivot" in body["message"]
    assert body["ik"]["position_error"] is None


@pytest.mark.parametrize(
    "body, loc",
    [
        ({"pose": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}, ["body", "pose"]),
        ({"pose": (2 * np.eye(4)).tolist()}, ["body", "pose"]),
        ({"pose": np.eye(4).tolist(), "q0": [0.0] * 3}, ["body", "q0"]),
    ],
)
def test_pose_to_cylinders_bad_input_is_422(client, body, loc):
    r = client.post(f"{PILE}/pose-to-cylinders", json=body)
    assert r.status_code == 422 and loc in _locs(r), r.text


def test_openapi_lists_the_endpoints(client):
    paths = client.get("/openapi.json").json()["paths"]
    for p in ("/cylinders", "/cylinders/inverse", "/pose-to-cylinders"):
        assert f"/robots/{{robot_id}}{p}" in paths
