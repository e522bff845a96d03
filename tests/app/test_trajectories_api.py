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
def test_plan_and_sample(ro_client, method):
    r = ro_client.post("/trajectories", json=body(method=method, robot="glt_palletizer"))
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


@pytest.mark.slow
def test_limits_reported_and_fitted(ro_client):
    fast = body(durations=[0.5, 0.5], limits={"velocity": 0.5, "acceleration": 1.0})
    out = ro_client.post("/trajectories", json=fast).json()
    assert not out["limits"]["ok"]
    kinds = {v["quantity"] for v in out["limits"]["violations"]}
    assert kinds == {"velocity", "acceleration"}
    assert all(v["value"] > v["limit"] for v in out["limits"]["violations"])
    fitted = ro_client.post("/trajectories", json=fast | {"time_scaling": True}).json()
    assert fitted["limits"]["ok"]
    assert sum(fitted["durations"]) > 1.0
    binding = max(max(fitted["peaks"]["velocity"]) / 0.5,
                  max(fitted["peaks"]["acceleration"]) / 1.0)
    assert binding == pytest.approx(1.0, rel=0.01)


@pytest.mark.slow
def test_robot_speed_limits_are_checked(ro_client):
    """hyper_redundant_9dof has a 0.1 rad/s joint speed limit."""
    wp = [[0.0] * 9, [0.5] * 9]
    out = ro_client.post("/trajectories", json=body(waypoints=wp, durations=[1.0],
                                                 robot="hyper_redundant_9dof")).json()
    assert {v["quantity"] for v in out["limits"]["violations"]} == {"velocity"}
    fitted = ro_client.post("/trajectories", json=body(waypoints=wp, durations=[1.0],
                                                    robot="hyper_redundant_9dof",
                                                    time_scaling=True)).json()
    assert fitted["limits"]["ok"]
    assert max(fitted["peaks"]["velocity"]) == pytest.approx(0.1, rel=0.01)


def test_joint_position_limits_are_checked(ro_client):
    wp = [[0.0, 0.5, 0.0, 0.0, 0.0, 0.0], [0.0, 3.0, 0.0, 0.0, 0.0, 0.0]]  # shoulder > 158 deg
    out = ro_client.post("/trajectories", json=body(waypoints=wp, durations=[2.0],
                                                 robot="glt_palletizer")).json()
    v = out["limits"]["violations"]
    assert v and v[0]["quantity"] == "position" and v[0]["name"] == "shoulder"


@pytest.mark.slow
def test_plot_is_a_png(ro_client):
    r = ro_client.post("/trajectories/plot", json=body(method="sextic", robot="glt_palletizer"))
    assert r.status_code == 200
    assert r.headers["content-type"] == "image/png"
    assert r.content[:8] == b"\x89PNG\r\n\x1a\n" and len(r.content) > 10_000


def test_cartesian_line_and_ellipse(ro_client):
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 200, 900]},
        "points": 30, "duration": 5.0, "dt": 0.05})
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["tracking"]["max_waypoint_error"] < 1e-6
    assert out["tracking"]["max_deviation"] < 5.0
    assert np.asarray(out["waypoints_q"]).shape == (30, 6)
    r = ro_client.post("/trajectories/cartesian", json={
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
def test_errors_name_the_field(ro_client, payload, status, field):
    r = ro_client.post("/trajectories", json=payload)
    assert r.status_code == status, r.text
    assert any(field in e["loc"] for e in r.json()["detail"]), r.json()


def test_cartesian_errors(ro_client):
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [6000, 0, 0]}})
    assert r.status_code == 422 and "path" in r.json()["detail"][0]["loc"]
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "spiral", "end": [1, 2, 3]}})
    assert r.status_code == 422
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 0, 900]},
        "q0": [0.0] * 5})
    assert r.status_code == 422 and "q0" in r.json()["detail"][0]["loc"]
    r = ro_client.post("/trajectories/cartesian", json={
        "robot": "glt_palletizer", "path": {"kind": "line", "end": [-4e245, 0, 0]}})
    assert r.status_code == 422 and "end" in r.json()["detail"][0]["loc"]


# ---- time scaling: uniform and optimal, hydraulics, jerk-limited moves ---------------------
GLT_LIMITS = {"velocity": 1.0, "acceleration": 2.0}
#: pile_driver: boom and stick extend together (the pump binds) / the boom comes down alone
#: (its cylinder's retraction speed binds).
PUMP_MOVE = [[0.0, 0.1, -0.9, -0.5, 0.0, 0.0], [0.0, 0.9, -0.1, -0.5, 0.0, 0.0]]
RETRACT_MOVE = [[0.0, 0.9, -0.5, -0.5, 0.0, 0.0], [0.0, 0.1, -0.5, -0.5, 0.0, 0.0]]


def _png_size(content: bytes) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk."""
    return int.from_bytes(content[16:20], "big"), int.from_bytes(content[20:24], "big")


def test_optimal_is_faster_than_uniform_and_binds_throughout(ro_client):
    base = body(method="smooth", robot="glt_palletizer", limits=GLT_LIMITS)
    uniform = ro_client.post("/trajectories", json=base | {"time_scaling": "uniform"}).json()
    legacy = ro_client.post("/trajectories", json=base | {"time_scaling": True}).json()
    optimal = ro_client.post("/trajectories", json=base | {"time_scaling": "optimal"}).json()
    assert legacy["duration"] == uniform["duration"]  # true is 'uniform'
    assert uniform["timing"]["time_scaling"] == "uniform"
    assert optimal["timing"]["time_scaling"] == "optimal"
    assert optimal["timing"]["optimal"]["grid"] >= 500
    assert uniform["limits"]["ok"] and optimal["limits"]["ok"]
    assert optimal["duration"] < 0.8 * uniform["duration"]
    np.testing.assert_allclose(np.asarray(optimal["q"])[[0, -1]], [GLT_ABC[0], GLT_ABC[2]],
                               atol=1e-9)
    # Uniform: a limit binds around one instant; optimal: at almost every sample.
    busy = [bool(b) for b in optimal["binding"]]
    assert sum(busy) >= 0.95 * len(busy)
    assert sum(bool(b) for b in uniform["binding"]) < 0.2 * len(uniform["binding"])
    names = {n for b in optimal["binding"] for n in b}
    assert names <= {f"{j} {k}" for j in ("waist", "shoulder", "elbow", "wrist_roll",
                                          "wrist_pitch", "wrist_yaw")
                     for k in ("velocity", "acceleration")}
    assert optimal["hydraulics"] is None  # no cylinders
    none = ro_client.post("/trajectories", json=base).json()
    assert none["timing"]["time_scaling"] == "none" and none["duration"] == pytest.approx(4.0)


def test_optimal_needs_no_durations_and_jerk_keeps_the_motion_smooth(ro_client):
    wp = {"method": "smooth", "waypoints": GLT_ABC, "robot": "glt_palletizer", "dt": 0.01}
    plain = ro_client.post("/trajectories", json=wp | {"time_scaling": "optimal",
                                                     "limits": GLT_LIMITS}).json()
    jerk = ro_client.post("/trajectories", json=wp | {
        "time_scaling": "optimal", "limits": GLT_LIMITS | {"jerk": 10.0}}).json()
    assert plain["limits"]["ok"] and jerk["limits"]["ok"]
    assert max(jerk["peaks"]["jerk"]) <= 10.0 * (1 + 1e-9)
    assert jerk["continuity"]["acceleration"] < 1e-6
    assert plain["duration"] < jerk["duration"] < 1.5 * plain["duration"]


@pytest.mark.parametrize(("move", "binds"), [(PUMP_MOVE, "pump"),
                                             (RETRACT_MOVE, "boom retraction")])
def test_pile_driver_reports_what_binds_and_its_peak_speeds(ro_client, move, binds):
    out = ro_client.post("/trajectories", json={
        "waypoints": move, "robot": "pile_driver", "time_scaling": "optimal", "dt": 0.005,
        "limits": {"acceleration": 5.0}}).json()
    assert out["limits"]["ok"], out["limits"]
    n = len(out["binding"])
    assert all(binds in b for b in out["binding"][int(0.4 * n): int(0.6 * n)])
    hyd = out["hydraulics"]
    boom = hyd["cylinders"]["boom"]
    assert boom["max_extension_speed"] == 150.0 and boom["max_retraction_speed"] == 220.0
    assert boom["peak_extension_speed"] <= 150.0 * (1 + 1e-6)
    assert boom["peak_retraction_speed"] <= 220.0 * (1 + 1e-6)
    assert hyd["pump"]["pump_flow"] == 40.0 and hyd["pump"]["peak_flow"] <= 40.0 * (1 + 1e-6)
    if binds == "pump":
        assert hyd["pump"]["peak_flow"] == pytest.approx(40.0, rel=1e-3)
    else:
        assert boom["peak_retraction_speed"] == pytest.approx(220.0, rel=1e-3)


def test_a_smaller_pump_slows_the_move_and_uniform_keeps_the_hydraulics_too(ro_client):
    base = {"waypoints": PUMP_MOVE, "robot": "pile_driver", "dt": 0.01,
            "time_scaling": "optimal"}
    big = ro_client.post("/trajectories", json=base | {"limits": {"acceleration": 5.0}}).json()
    small = ro_client.post("/trajectories", json=base | {
        "limits": {"acceleration": 5.0, "pump_flow": 20.0}}).json()
    assert small["duration"] > 1.5 * big["duration"]
    assert small["hydraulics"]["pump"]["peak_flow"] <= 20.0 * (1 + 1e-6)
    uniform = ro_client.post("/trajectories", json=base | {
        "time_scaling": "uniform", "durations": [1.0], "method": "quintic"}).json()
    assert uniform["limits"]["ok"] and uniform["duration"] > big["duration"]
    assert uniform["hydraulics"]["pump"]["peak_flow"] == pytest.approx(40.0, rel=2e-3)
    # Without any scaling an overly fast move is reported: the pump and a cylinder.
    fast = ro_client.post("/trajectories", json=base | {
        "time_scaling": "none", "durations": [0.3], "method": "quintic"}).json()
    names = {(v["name"], v["quantity"]) for v in fast["limits"]["violations"]}
    assert ("pump", "flow") in names and ("boom", "extension") in names


INFEASIBLE = [
    ({"limits": {"velocity": 0}}, ["body", "limits", "velocity"]),
    ({"limits": {"acceleration": 1.0, "pump_flow": 0}}, ["body", "limits", "pump_flow"]),
    ({}, ["body", "limits", "acceleration"]),
    ({"time_scaling": "uniform", "limits": {"acceleration": 1.0}}, ["body", "durations"]),
    ({"time_scaling": "fastest"}, ["body", "time_scaling"]),
    ({"grid": 3, "limits": {"acceleration": 1.0}}, ["body", "grid"]),
    ({"robot": "glt_palletizer", "limits": {"acceleration": 1.0, "pump_flow": 10.0}},
     ["body", "limits", "pump_flow"]),
]


def test_infeasible_limits_are_422_naming_the_field(ro_client):
    # One ro_client for all cases: each new app starts its own worker processes.
    for change, loc in INFEASIBLE:
        r = ro_client.post("/trajectories", json={"waypoints": PUMP_MOVE, "robot": "pile_driver",
                                               "time_scaling": "optimal"} | change)
        assert r.status_code == 422, (change, r.text)
        assert any(e["loc"][:len(loc)] == loc for e in r.json()["detail"]), r.json()


def test_jerk_limited_point_to_point(ro_client):
    lim = {"velocity": 2.0, "acceleration": 1.0, "jerk": 2.0}
    out = ro_client.post("/trajectories", json={
        "waypoints": [[0.0], [10.0]], "profile": "jerk_limited", "limits": lim}).json()
    assert out["duration"] == pytest.approx(10 / 2 + 2 / 1 + 1 / 2)  # d/V + V/A + A/J
    assert out["timing"]["profile"] == "jerk_limited" and out["limits"]["ok"]
    two = ro_client.post("/trajectories", json={
        "waypoints": [[0.0, 0.0], [10.0, 1.0]], "profile": "jerk_limited", "limits": lim,
        "end_velocity": [0.5, 0.1]}).json()
    assert two["limits"]["ok"] and two["timing"]["limiting_joint"] == "j1"
    np.testing.assert_allclose(two["qd"][-1], [0.5, 0.1], atol=1e-6)
    np.testing.assert_allclose(two["q"][-1], [10.0, 1.0], atol=1e-9)
    for change, loc in (({"waypoints": [[0.0], [1.0], [2.0]]}, "waypoints"),
                        ({"limits": {"velocity": 1.0, "acceleration": 1.0}}, "jerk"),
                        ({"end_velocity": [5.0]}, "end_velocity")):
        r = ro_client.post("/trajectories", json={"waypoints": [[0.0], [10.0]],
                                               "profile": "jerk_limited", "limits": lim} | change)
        assert r.status_code == 422 and any(loc in e["loc"] for e in r.json()["detail"]), r.text


@pytest.mark.slow
def test_plot_adds_cylinder_and_pump_panels_for_hydraulic_arms(ro_client):
    glt = ro_client.post("/trajectories/plot", json=body(method="sextic", robot="glt_palletizer"))
    pile = ro_client.post("/trajectories/plot", json={
        "waypoints": PUMP_MOVE, "robot": "pile_driver", "time_scaling": "optimal",
        "limits": {"acceleration": 5.0}})
    assert glt.status_code == 200 and pile.status_code == 200, pile.text
    w_glt, h_glt = _png_size(glt.content)
    w_pile, h_pile = _png_size(pile.content)
    assert w_glt == w_pile and h_pile - h_glt == 400  # two more panels of 2 in at 100 dpi


def test_cartesian_optimal_is_faster_and_still_on_the_line(ro_client):
    req = {"robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 200, 900]},
           "points": 30, "duration": 5.0, "limits": GLT_LIMITS}
    slow = ro_client.post("/trajectories/cartesian", json=req).json()
    fast = ro_client.post("/trajectories/cartesian", json=req | {"time_scaling": "optimal"}).json()
    assert fast["limits"]["ok"] and fast["timing"]["time_scaling"] == "optimal"
    assert fast["duration"] < slow["duration"]
    assert fast["tracking"]["max_deviation"] < 5.0
    r = ro_client.post("/trajectories/cartesian", json=req | {"time_scaling": "optimal",
                                                          "limits": {"velocity": 1.0}})
    assert r.status_code == 422 and ["body", "limits", "acceleration"] == \
        r.json()["detail"][0]["loc"]
