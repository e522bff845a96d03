"""POST /trajectories, /trajectories/plot and /trajectories/cartesian."""

from __future__ import annotations

import numpy as np
import pytest

GLT_ABC = np.radians(
    [[90, 53.75, 11.77, 0, 24.48, 0], [60, 23.88, 7.89, 0, 58.23, 0],
     [0, 26.59, 10.52, 0, 52.89, 0]]
).tolist()


def body(**kw):
    return {"method": "quintic", "waypoints": GLT_ABC, "durations": [2.0, 2.0], "dt": 0.01} | kw


@pytest.mark.parametrize("method", ["quintic", "sextic", "bspline5", "smooth"])
def test_plan_and_sample(client, method):
    r = client.post("/trajectories", json=body(method=method, robot="glt_palletizer"))
    assert r.status_code == 200, r.text
    out = r.json()
    t = np.asarray(out["t"])
    assert t[0] == 0 and t[-1] == pytest.approx(4.0) and len(t) == 401
    for key in ("q", "qd", "qdd", "qddd"):
        assert np.asarray(out[key]).shape == (401, 6)
    np.testing.assert_allclose(np.asarray(out["q"])[[0, -1]], [GLT_ABC[0], GLT_ABC[2]],
                               atol=1e-9)
    assert out["limits"] == {"ok": True, "violations": []}
    c = out["continuity"]
    assert c["position"] < 1e-9 and c["velocity"] < 1e-9 and c["acceleration"] < 1e-9
    if method != "quintic":
        assert c["jerk"] < 1e-9


def test_limits_reported_and_fitted(client):
    fast = body(durations=[0.5, 0.5], limits={"velocity": 0.5, "acceleration": 1.0})
    out = client.post("/trajectories", json=fast).json()
    assert not out["limits"]["ok"]
    kinds = {v["quantity"] for v in out["limits"]["violations"]}
    assert kinds == {"velocity", "acceleration"}
    assert all(v["value"] > v["limit"] for v in out["limits"]["violations"])
    fitted = client.post("/trajectories", json=fast | {"time_scaling": True}).json()
    assert fitted["limits"]["ok"]
    assert sum(fitted["durations"]) > 1.0
    binding = max(max(fitted["peaks"]["velocity"]) / 0.5,
                  max(fitted["peaks"]["acceleration"]) / 1.0)
    assert binding == pytest.approx(1.0, rel=0.01)


def test_robot_speed_limits_are_checked(client):
    """hyper_redundant_9dof has a 0.1 rad/s joint speed limit."""
    wp = [[0.0] * 9, [0.5] * 9]
    out = client.post("/trajectories", json=body(waypoints=wp, durations=[1.0],
                                                 robot="hyper_redundant_9dof")).json()
    assert {v["quantity"] for v in out["limits"]["violations"]} == {"velocity"}
    fitted = client.post("/trajectories", json=body(waypoints=wp, durations=[1.0],
                                                    robot="hyper_redundant_9dof",
                                                    time_scaling=True)).json()
    assert fitted["limits"]["ok"]
    assert max(fitted["peaks"]["velocity"]) == pytest.approx(0.1, rel=0.01)


def test_joint_position_limits_are_checked(client):
    wp = [[0.0, 0.5, 0.0, 0.0, 0.0, 0.0], [0.0, 3.0, 0.0, 0.0, 0.0, 0.0]]  # shoulder > 158 deg
    out = client.post("/trajectories", json=body(waypoints=wp, durations=[2.0],
                                                 robot="glt_palletizer")).json()
    v = out["limits"]["violations"]
    assert v and v[0]["quantity"] == "position" and v[0]["name"] == "shoulder"


def test_plot_is_a_png(client):
    r = client.post("/trajectories/plot", json=body(method="sextic", robot="glt_palletizer"))
    assert r.status_code == 200
    assert r.headers["content-type"] == "image/png"
    assert r.content[:8] == b"\x89PNG\r\n\x1a\n" and len(r.content) > 10_000


def test_cartesian_line_and_ellipse(client):
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 200, 900]},
        "points": 30, "duration": 5.0, "dt": 0.05})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["tracking"]["max_waypoint_error"] < 1e-6
    assert out["tracking"]["max_deviation"] < 5.0
    assert np.asarray(out["waypoints_q"]).shape == (30, 6)
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer",
        "path": {"kind": "ellipse", "center": [1200, 0, 800], "radii": [200, 100],
                 "normal": [1, 0, 0]},
        "points": 60, "duration": 8.0})
    assert r.status_code == 200, r.text
    assert r.json()["tracking"]["max_deviation"] < 5.0


ERRORS = [
    (body(waypoints=[GLT_ABC[0]], durations=[]), 422, "waypoints"),
    (body(durations=[2.0]), 422, "durations"),
    (body(durations=[2.0, 0.0]), 422, "durations"),
    (body(durations=[2.0, -1.0]), 422, "durations"),
    (body(dt=0), 422, "dt"),
    (body(dt=-0.1), 422, "dt"),
    (body(dt=1e-6), 422, "dt"),
    (body(method="cubic"), 422, "method"),
    (body(waypoints=[[0.0] * 6, [0.0] * 5, [0.0] * 6]), 422, "waypoints"),
    (body(robot="glt_palletizer", waypoints=[[0.0] * 5] * 3), 422, "waypoints"),
    (body(robot="nope"), 404, "robot"),
    (body(limits={"velocity": -1}), 422, "velocity"),
    (body(limits={"velocity": [1, 2]}), 422, "velocity"),
    (body(time_scaling=True), 422, "limits"),
    (body(method="sextic", velocities=[[0.0] * 6] * 3), 422, "velocities"),
]


@pytest.mark.parametrize("payload, status, field", ERRORS)
def test_errors_name_the_field(client, payload, status, field):
    r = client.post("/trajectories", json=payload)
    assert r.status_code == status, r.text
    assert any(field in e["loc"] for e in r.json()["detail"]), r.json()


def test_cartesian_errors(client):
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [6000, 0, 0]}})
    assert r.status_code == 422 and "path" in r.json()["detail"][0]["loc"]
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "spiral", "end": [1, 2, 3]}})
    assert r.status_code == 422
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 0, 900]},
        "q0": [0.0] * 5})
    assert r.status_code == 422 and "q0" in r.json()["detail"][0]["loc"]
    r = client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [-4e245, 0, 0]}})
    assert r.status_code == 422 and "end" in r.json()["detail"][0]["loc"]
