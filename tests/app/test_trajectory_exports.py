"""``GET /jobs/{id}/trajectory``: a finished job's joint trajectory as json, csv or a ROS
``trajectory_msgs/JointTrajectory``.

Motion jobs run through a served app (its local workers), and their exports are compared
with the result the service stored (``GET /jobs/{id}/result`` and the store's text). The
results of the other kinds (multiarm, path, tracking) are written to the store as a worker
would leave them, each checked against its kind's result model first, with samples whose
derivatives are known in closed form (quadratics in t, which second-order differences
reproduce exactly). Motion results store samples, not a spline: there is nothing to re-sample.
"""

from __future__ import annotations

import csv
import io
import json
import time
from collections.abc import Iterator

import numpy as np
import pytest
from fastapi.testclient import TestClient
from stored_jobs import store_job as _store

from app.config import Settings
from app.main import create_app
from app.trajectory_export import durations
from kinematics.library import builtin_model
from kinematics.rigs import builtin_rig

GLT = "glt_palletizer"
GLT_START = [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
GLT_GOAL = [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]
#: The tunnel arm: joints 2 (telescope) and 6 (feed) are prismatic, in mm.
DRILL = "tunnel_drill_arm"
DRILL_START = [0.0, -1.2, 6000.0, 0.0, 1.2, 1.5, 1000.0]
DRILL_GOAL = [0.4, -1.0, 7000.0, 0.5, 1.4, 1.6, 3000.0]
DRILL_NAMES = ["swing", "pitch", "telescope", "roll", "pitch_compensation",
               "swing_compensation", "feed"]
PRISMATIC = np.array([False, False, True, False, False, False, True])
ENDED = ("succeeded", "failed", "cancelled")


def _wait(client: TestClient, job_id: str, timeout: float = 240.0) -> dict:
    deadline = time.monotonic() + timeout
    while True:
        job = client.get(f"/jobs/{job_id}").json()
        if job["status"] in ENDED:
            return job
        assert time.monotonic() < deadline, f"job {job_id} still {job['status']}"
        time.sleep(0.1)


@pytest.fixture(scope="module")
def served(tmp_path_factory) -> Iterator[tuple[TestClient, dict[str, str]]]:
    """A served app (2 local workers) that has run a one-problem motion job of the
    palletizer and a two-problem batch of the tunnel arm whose second start is outside the
    telescope's limits (status ``out_of_limits``, no trajectory)."""
    data_dir = tmp_path_factory.mktemp("exports")
    settings = Settings(no_viewer=True, data_dir=data_dir, workers=2)
    bodies = {
        "glt": {"robot": GLT, "start": GLT_START, "goal": {"q": GLT_GOAL},
                "planner": "rrt_connect", "time_limit": 10},
        "drill": {"robot": DRILL, "planner": "rrt_connect", "time_limit": 10, "problems": [
            {"start": DRILL_START, "goal": {"q": DRILL_GOAL}},
            {"start": [0.0, -1.2, 20000.0, 0.0, 1.2, 1.5, 1000.0],
             "goal": {"q": DRILL_GOAL}}]},
    }
    with TestClient(create_app(settings)) as c:
        ids = {}
        for name, params in bodies.items():
            r = c.post("/jobs", json={"kind": "motion", "params": params})
            assert r.status_code == 202, r.text
            ids[name] = r.json()["id"]
        for job_id in ids.values():
            job = _wait(c, job_id)
            assert job["status"] == "succeeded", job
        yield c, ids


def _detail(r) -> dict:
    (detail,) = r.json()["detail"]
    return detail


def _seconds(stamp: dict) -> float:
    assert isinstance(stamp["sec"], int) and isinstance(stamp["nanosec"], int)
    assert 0 <= stamp["nanosec"] < 1_000_000_000
    return stamp["sec"] + stamp["nanosec"] * 1e-9


# ---- motion jobs through the service --------------------------------------------------------
@pytest.mark.slow
def test_joint_trajectory_of_a_motion_job_has_the_stored_samples_at_each_time(served):
    c, ids = served
    job_id = ids["glt"]
    result = c.get(f"/jobs/{job_id}/result").json()
    stored = json.loads(c.app.state.store.job_result(job_id))
    assert stored == result and result["status"] == "ok"
    traj = result["trajectory"]
    r = c.get(f"/jobs/{job_id}/trajectory", params={"format": "joint_trajectory"})
    assert r.status_code == 200 and r.headers["content-type"] == "application/json"
    msg = r.json()
    assert set(msg) == {"header", "joint_names", "points"}
    assert msg["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "world"}
    assert msg["joint_names"] == result["joints"] == [
        "waist", "shoulder", "elbow", "wrist_roll", "wrist_pitch", "flange_roll"]
    points = msg["points"]
    assert len(points) == len(traj["t"]) == 200
    for k, p in enumerate(points):
        assert set(p) == {"positions", "velocities", "accelerations", "effort",
                          "time_from_start"}
        assert abs(_seconds(p["time_from_start"]) - traj["t"][k]) <= 1e-9
        # every joint revolute: rad, as stored
        np.testing.assert_allclose(p["positions"], traj["q"][k], rtol=0, atol=1e-9)
        np.testing.assert_allclose(p["velocities"], traj["qd"][k], rtol=0, atol=1e-9)
        np.testing.assert_allclose(p["accelerations"], traj["qdd"][k], rtol=0, atol=1e-9)
        assert p["effort"] == []
    # from the start asked for to the goal, over the stored duration
    np.testing.assert_allclose(points[0]["positions"], GLT_START, atol=1e-9)
    np.testing.assert_allclose(points[-1]["positions"], GLT_GOAL, atol=1e-9)
    assert abs(_seconds(points[-1]["time_from_start"]) - traj["duration"]) <= 1e-9
    times = [_seconds(p["time_from_start"]) for p in points]
    assert times[0] == 0.0 and all(b > a for a, b in zip(times, times[1:]))


def test_json_is_the_default_and_states_its_units(served):
    c, ids = served
    result = c.get(f"/jobs/{ids['glt']}/result").json()
    out = c.get(f"/jobs/{ids['glt']}/trajectory").json()
    assert out == c.get(f"/jobs/{ids['glt']}/trajectory?format=json").json()
    assert (out["job"], out["kind"], out["robot"]) == (ids["glt"], "motion", GLT)
    assert out["joint_names"] == result["joints"]
    assert out["joint_types"] == ["revolute"] * 6
    assert out["units"] == {"time_from_start": "s", "positions": ["rad"] * 6,
                            "velocities": ["rad/s"] * 6, "accelerations": ["rad/s^2"] * 6}
    assert out["derivatives"] == "stored"
    assert out["duration"] == pytest.approx(result["trajectory"]["duration"], abs=1e-12)
    traj = result["trajectory"]
    assert [p["time_from_start"] for p in out["points"]] == traj["t"]
    assert [p["positions"] for p in out["points"]] == traj["q"]
    assert [p["velocities"] for p in out["points"]] == traj["qd"]
    assert [p["accelerations"] for p in out["points"]] == traj["qdd"]


def test_csv_has_one_column_per_joint_and_quantity_in_the_service_units(served):
    c, ids = served
    traj = c.get(f"/jobs/{ids['glt']}/result").json()["trajectory"]
    r = c.get(f"/jobs/{ids['glt']}/trajectory?format=csv")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert f'filename="{ids["glt"]}-trajectory.csv"' in r.headers["content-disposition"]
    assert r.headers["x-joint-units"] == "rad,rad,rad,rad,rad,rad"
    rows = list(csv.reader(io.StringIO(r.text)))
    names = ["waist", "shoulder", "elbow", "wrist_roll", "wrist_pitch", "flange_roll"]
    assert rows[0] == (["time_s"] + [f"{n}_pos" for n in names] + [f"{n}_vel" for n in names]
                       + [f"{n}_acc" for n in names])
    table = np.array(rows[1:], dtype=float)
    assert table.shape == (200, 19)
    # written to round-trip: the very floats stored
    assert table[:, 0].tolist() == traj["t"]
    assert table[:, 1:7].tolist() == traj["q"]
    assert table[:, 7:13].tolist() == traj["qd"]
    assert table[:, 13:19].tolist() == traj["qdd"]


def test_prismatic_joints_are_m_in_joint_trajectory_and_mm_in_json_and_csv(served):
    c, ids = served
    job_id = ids["drill"]
    result = c.get(f"/jobs/{job_id}/result").json()
    first = result["problems"][0]
    assert first["status"] == "ok" and result["joints"] == DRILL_NAMES
    traj = {k: np.array(first["trajectory"][k]) for k in ("t", "q", "qd", "qdd")}
    msg = c.get(f"/jobs/{job_id}/trajectory?format=joint_trajectory&problem=0").json()
    assert msg["joint_names"] == DRILL_NAMES
    for key, name in (("q", "positions"), ("qd", "velocities"), ("qdd", "accelerations")):
        got = np.array([p[name] for p in msg["points"]])
        # telescope and feed: mm -> m; the revolute joints as stored (rad)
        np.testing.assert_allclose(got[:, PRISMATIC], traj[key][:, PRISMATIC] / 1000.0,
                                   rtol=1e-15, atol=1e-12)
        np.testing.assert_array_equal(got[:, ~PRISMATIC], traj[key][:, ~PRISMATIC])
    # the telescope starts at 6000 mm: 6 m
    assert msg["points"][0]["positions"][2] == pytest.approx(6.0, abs=1e-12)
    assert msg["points"][-1]["positions"][6] == pytest.approx(3.0, abs=1e-12)
    out = c.get(f"/jobs/{job_id}/trajectory?problem=0").json()
    assert out["problem"] == 0
    assert out["units"]["positions"] == ["rad", "rad", "mm", "rad", "rad", "rad", "mm"]
    assert out["units"]["accelerations"][2] == "mm/s^2"
    assert out["joint_types"] == ["prismatic" if p else "revolute" for p in PRISMATIC]
    assert out["points"][0]["positions"] == DRILL_START
    r = c.get(f"/jobs/{job_id}/trajectory?problem=0&format=csv")
    assert r.headers["x-joint-units"] == "rad,rad,mm,rad,rad,rad,mm"
    assert f'filename="{job_id}-trajectory-problem-0.csv"' in r.headers["content-disposition"]
    table = np.array(list(csv.reader(io.StringIO(r.text)))[1:], dtype=float)
    np.testing.assert_array_equal(table[:, 1:8], traj["q"])


def test_a_batch_exports_each_solved_problem_or_the_one_chosen(served):
    c, ids = served
    job_id = ids["drill"]
    result = c.get(f"/jobs/{job_id}/result").json()
    assert result["problems"][1]["status"] == "out_of_limits"
    # without problem: a list of the problems with a trajectory
    listed = c.get(f"/jobs/{job_id}/trajectory").json()
    assert isinstance(listed, list) and [x["problem"] for x in listed] == [0]
    msgs = c.get(f"/jobs/{job_id}/trajectory?format=joint_trajectory").json()
    assert [m["problem"] for m in msgs] == [0]
    assert msgs[0]["joint_trajectory"] == c.get(
        f"/jobs/{job_id}/trajectory?format=joint_trajectory&problem=0").json()
    # the problem without one, one out of range, csv without a choice
    r = c.get(f"/jobs/{job_id}/trajectory?problem=1")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "problem"]
    assert "out_of_limits" in _detail(r)["msg"]
    r = c.get(f"/jobs/{job_id}/trajectory?problem=5")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "problem"]
    assert "0, 1" in _detail(r)["msg"]
    r = c.get(f"/jobs/{job_id}/trajectory?format=csv")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "problem"]
    r = c.get(f"/jobs/{job_id}/trajectory?arm=left")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "arm"]


def test_a_one_problem_job_takes_neither_arm_nor_problem(served):
    c, ids = served
    for query, loc in (("arm=left", ["query", "arm"]), ("problem=0", ["query", "problem"])):
        r = c.get(f"/jobs/{ids['glt']}/trajectory?{query}")
        assert r.status_code == 422 and _detail(r)["loc"] == loc, r.text


# ---- other kinds, stored as a worker leaves them ----------------------------------------
#: Per joint of the tunnel arm: q = A + B t + C t² (rad / mm).
A = np.array([0.1, -1.2, 6000.0, 0.0, 1.2, 1.5, 500.0])
B = np.array([0.02, 0.01, 150.0, -0.05, 0.0, 0.03, 80.0])
C = np.array([-0.004, 0.002, 12.0, 0.01, 0.0, -0.001, -5.0])


def _quadratic(t: np.ndarray, shift: float = 0.0) -> np.ndarray:
    return A + shift + np.outer(t, B) + np.outer(t * t, C)


def _multiarm_result(t: np.ndarray) -> dict:
    arms = {}
    for k, arm in enumerate(("left", "middle", "right")):
        arms[arm] = {
            "holes": [[9000.0, 0.0, 1000.0]], "hole_ids": [f"{arm}[0]"],
            "q": _quadratic(t, shift=0.1 * k).tolist(), "move_starts_s": [0.0],
            "end_s": float(t[-1]), "travel_m": 1.0, "sequence_length_m": 0.0,
            "planner_counts": {"iapf": 1}, "peak_acceleration": [0.1] * 7,
            "max_rotational_acceleration": 0.1, "boom_time_s": 1.0,
            "boom_time_distance_order_s": 1.0}
    pairs = ("left-middle", "left-right", "middle-right")
    return {"rig": "tunnel_jumbo", "planner": "iapf", "success": True, "messages": [],
            "notes": [], "middle_park": "last_hole", "t": t.tolist(), "arms": arms,
            "min_distance": {p: [500.0] * len(t) for p in pairs},
            "min_distance_overall": {p: 500.0 for p in pairs}, "collisions": 0,
            "collisions_by_pair": {p: 0 for p in pairs},
            "travel_m": {a: 1.0 for a in arms}, "total_travel_m": 3.0, "cost": "distance",
            "boom_time_s": 3.0, "boom_time_distance_order_s": 3.0, "boom_time_saved_s": 0.0,
            "acceleration_bound": 0.25, "check_dt": 0.01, "samples": 100, "runtime_s": 1.0}


MULTIARM_T = np.arange(0.0, 10.0 + 1e-9, 0.5)


def test_multiarm_exports_the_arm_chosen_with_derivatives_estimated(client):
    _store(client, "face", "multiarm", {"holes": {}}, _multiarm_result(MULTIARM_T))
    assert [a for a in builtin_rig("tunnel_jumbo").arms] == ["left", "middle", "right"]
    out = client.get("/jobs/face/trajectory?arm=middle").json()
    assert (out["arm"], out["robot"], out["derivatives"]) == (
        "middle", "tunnel_jumbo-middle", "finite_differences")
    assert out["joint_names"] == DRILL_NAMES
    assert out["units"]["positions"] == ["rad", "rad", "mm", "rad", "rad", "rad", "mm"]
    q = np.array([p["positions"] for p in out["points"]])
    qd = np.array([p["velocities"] for p in out["points"]])
    qdd = np.array([p["accelerations"] for p in out["points"]])
    np.testing.assert_array_equal(q, _quadratic(MULTIARM_T, 0.1))
    # second-order differences are exact on a quadratic: q' = B + 2Ct, q'' = 2C
    np.testing.assert_allclose(qd, B + 2 * np.outer(MULTIARM_T, C), rtol=0, atol=1e-7)
    np.testing.assert_allclose(qdd, np.broadcast_to(2 * C, qdd.shape), rtol=0, atol=1e-6)
    assert [p["time_from_start"] for p in out["points"]] == MULTIARM_T.tolist()
    # ROS: m for the telescope and the feed
    msg = client.get("/jobs/face/trajectory?arm=left&format=joint_trajectory").json()
    got = np.array([p["positions"] for p in msg["points"]])
    want = _quadratic(MULTIARM_T)
    np.testing.assert_allclose(got[:, PRISMATIC], want[:, PRISMATIC] / 1000, atol=1e-12)
    np.testing.assert_array_equal(got[:, ~PRISMATIC], want[:, ~PRISMATIC])
    acc = np.array([p["accelerations"] for p in msg["points"]])
    np.testing.assert_allclose(acc[:, 2], 2 * C[2] / 1000, atol=1e-9)  # m/s²
    r = client.get("/jobs/face/trajectory?arm=right&format=csv")
    assert r.status_code == 200 and 'trajectory-arm-right.csv"' in r.headers[
        "content-disposition"]
    table = np.array(list(csv.reader(io.StringIO(r.text)))[1:], dtype=float)
    np.testing.assert_array_equal(table[:, 1:8], _quadratic(MULTIARM_T, 0.2))


def test_multiarm_without_an_arm_lists_every_arm_and_refuses_a_wrong_one(client):
    _store(client, "face", "multiarm", {"holes": {}}, _multiarm_result(MULTIARM_T))
    listed = client.get("/jobs/face/trajectory").json()
    assert [x["arm"] for x in listed] == ["left", "middle", "right"]
    for k, x in enumerate(listed):
        assert x["points"][0]["positions"] == (A + 0.1 * k).tolist()
    msgs = client.get("/jobs/face/trajectory?format=joint_trajectory").json()
    assert [m["arm"] for m in msgs] == ["left", "middle", "right"]
    assert all(m["joint_trajectory"]["joint_names"] == DRILL_NAMES for m in msgs)
    r = client.get("/jobs/face/trajectory?format=csv")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "arm"]
    assert "left, middle, right" in _detail(r)["msg"]
    r = client.get("/jobs/face/trajectory?arm=top")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "arm"]
    assert "'top'" in _detail(r)["msg"] and "left, middle, right" in _detail(r)["msg"]
    r = client.get("/jobs/face/trajectory?problem=0")
    assert r.status_code == 422 and _detail(r)["loc"] == ["query", "problem"]


def _path_result(robot: str | None) -> dict:
    t = np.linspace(0.0, 2.0, 5)
    q = np.outer(np.ones(5), GLT_START) + np.outer(t, [0.5, 0, 0, 0, 0, 0])
    trajectory = {"t": t.tolist(), "q": q.tolist(),
                  "qd": np.outer(np.ones(5), [0.5, 0, 0, 0, 0, 0]).tolist(),
                  "qdd": np.zeros((5, 6)).tolist(), "waypoints": [q[0].tolist(), q[-1].tolist()]}
    out = {"path": [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]], "length": 1.7, "min_clearance": None,
           "runtime_s": 0.1, "convergence": [], "algorithm": "auto", "evaluations": 1,
           "success": True, "status": "ok", "message": "ok", "raw_length": 1.7,
           "joint_path": None, "trajectory": None, "cylinders": None}
    if robot is not None:
        out |= {"robot": robot, "planner": "tool_space", "joint_path": q.tolist(),
                "trajectory": trajectory, "arm_min_clearance": 10.0,
                "tool_samples": [[0.0, 0.0, 0.0]]}
    return out


def test_path_and_tracking_results_export_their_joint_samples(client):
    _store(client, "arm", "path", {"robot": GLT}, _path_result(GLT))
    out = client.get("/jobs/arm/trajectory").json()
    assert (out["kind"], out["robot"], out["derivatives"]) == ("path", GLT, "stored")
    assert out["joint_names"] == [j.name for j in builtin_model(GLT).joints]
    assert [p["velocities"][0] for p in out["points"]] == [0.5] * 5
    assert out["duration"] == 2.0
    t = np.linspace(0.0, 4.0, 9)
    q = np.outer(t, np.linspace(0.1, 0.9, 9))  # 9 joints, constant speed
    tracking = {
        "robot": "hyper_redundant_9dof", "task": {"kind": "line"}, "controller": "pi",
        "tune": None, "mean_error": 0.1, "max_error": 0.2, "std_error": 0.05,
        "kp": [0.5, 0.5], "ki": 1.0, "seed": 0, "t": t.tolist(),
        "x_desired": [[0.0, 0.0, 0.0]] * 9, "x_actual": [[0.0, 0.0, 0.0]] * 9,
        "q": q.tolist(), "errors": [0.0] * 9, "joint_speed_max": 0.9, "saturated_steps": 0,
        "fitness_history": []}
    _store(client, "track", "tracking", {"robot": "hyper_redundant_9dof"}, tracking)
    msg = client.get("/jobs/track/trajectory?format=joint_trajectory").json()
    assert len(msg["joint_names"]) == 9
    assert [p["time_from_start"] for p in msg["points"]][1] == {"sec": 0,
                                                                "nanosec": 500_000_000}
    np.testing.assert_allclose([p["velocities"] for p in msg["points"]],
                               np.broadcast_to(np.linspace(0.1, 0.9, 9), (9, 9)), atol=1e-12)
    np.testing.assert_allclose([p["accelerations"] for p in msg["points"]], 0.0, atol=1e-12)


# ---- errors -------------------------------------------------------------------------------
def test_an_unknown_job_is_404(client):
    r = client.get("/jobs/0000000000000000/trajectory")
    assert r.status_code == 404 and _detail(r)["loc"] == ["path", "job_id"]


def test_a_job_not_succeeded_is_409_saying_its_status(client):
    _store(client, "waiting", "motion", {"robot": GLT}, None, status="queued")
    r = client.get("/jobs/waiting/trajectory?format=csv")
    assert r.status_code == 409 and _detail(r)["loc"] == ["path", "job_id"]
    assert "is queued" in _detail(r)["msg"]
    _store(client, "broke", "motion", {"robot": GLT}, None, status="failed",
           error="time limit of 5 s exceeded")
    r = client.get("/jobs/broke/trajectory")
    assert r.status_code == 409
    assert "is failed" in _detail(r)["msg"] and "time limit" in _detail(r)["msg"]


def test_a_bad_format_is_422_at_the_query_field(client):
    _store(client, "arm", "path", {"robot": GLT}, _path_result(GLT))
    for fmt in ("xml", "JSON", ""):
        r = client.get(f"/jobs/arm/trajectory?format={fmt}")
        assert r.status_code == 422 and _detail(r)["loc"] == ["query", "format"], fmt


def test_results_without_a_trajectory_are_422_naming_the_kinds_with_one(client):
    _store(client, "ws", "echo", {"value": 1}, {"value": 1})
    r = client.get("/jobs/ws/trajectory")
    assert r.status_code == 422 and _detail(r)["loc"] == ["path", "job_id"]
    msg = _detail(r)["msg"]
    assert "'echo'" in msg and all(k in msg for k in ("motion", "path", "multiarm",
                                                      "tracking"))
    _store(client, "toolonly", "path", {}, _path_result(None))
    r = client.get("/jobs/toolonly/trajectory")
    assert r.status_code == 422 and "without a robot" in _detail(r)["msg"]
    # a motion that found no path
    unsolved = {"robot": GLT, "joints": [j.name for j in builtin_model(GLT).joints],
                "status": "no_path", "message": "no path", "path": [], "length": None,
                "planning_time_s": 1.0, "simplify_time_s": 0.0, "min_clearance": None,
                "goal": None, "pairs": [], "planner": "rrt_connect", "resolution": 0.01,
                "stats": {}, "trajectory": None}
    _store(client, "stuck", "motion", {"robot": GLT}, unsolved)
    r = client.get("/jobs/stuck/trajectory?format=joint_trajectory")
    assert r.status_code == 422 and _detail(r)["loc"] == ["path", "job_id"]
    assert "no_path" in _detail(r)["msg"]


def test_a_robot_deleted_since_is_422_since_its_joint_units_are_unknown(client):
    _store(client, "orphan", "path", {"robot": "gone"}, _path_result("gone"))
    r = client.get("/jobs/orphan/trajectory")
    assert r.status_code == 422 and _detail(r)["loc"] == ["path", "job_id"]
    assert "'gone'" in _detail(r)["msg"] and "no longer stored" in _detail(r)["msg"]


def test_times_are_rounded_to_the_nearest_nanosecond():
    sec, nanosec = durations(np.array([0.0, 1.5, 2.9999999999, 3.0000000004, 61.25]))
    assert sec == [0, 1, 3, 3, 61]
    assert nanosec == [0, 500_000_000, 0, 0, 250_000_000]
    sec, nanosec = durations(np.array([0.1234567894, 7.0000000016]))
    assert (sec, nanosec) == ([0, 7], [123_456_789, 2])
