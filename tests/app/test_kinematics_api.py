"""FK, IK, Jacobian and workspace over HTTP, checked against the papers' printed numbers,
and the error statuses of the REST contract (docs/API.md).

Reference numbers come from tests/data/paper_tables.json (angles in degrees, lengths in mm
there; the API takes radians and mm).
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from app import responses

GLT = "/robots/glt_palletizer"
PILE = "/robots/pile_driver"
HYPER = "/robots/hyper_redundant_9dof"

TABLES = json.loads((Path(__file__).parents[1] / "data" / "paper_tables.json").read_text())
# Paper 004, Table 2 and eqs. 14-16: joint angles (deg) -> printed tool pose TT1..TT3
# (rotations to 4 decimals, positions in mm to 2 decimals).
GLT_FK = [
    (row["q_deg"], row["T"]) for row in TABLES["glt_palletizer"]["fk_matrices_eq14_16"]
]
# Paper 000, section 3.5: joint angles (deg) -> printed tool x, y (cm, times 10 -> mm). Only x
# and y follow from Table 1 (see fk_quality_note), so z and rotations are not checked here.
PILE_FK_XY = [
    (row["q_deg"], tuple(10.0 * v for v in row["paper_xyz_cm"][:2]))
    for row in TABLES["pile_driver"]["fk_checks_cm"]
]


def rad(deg) -> list[float]:
    return np.deg2rad(np.asarray(deg, dtype=float)).tolist()


def names_field(detail: list[dict], field: str) -> bool:
    """Whether some error entry's ``loc`` names ``field``."""
    return any(field in entry.get("loc", []) for entry in detail)


def fk_poses(client, url: str, q) -> np.ndarray:
    r = client.post(f"{url}/fk", json={"q": np.asarray(q, dtype=float).tolist()})
    assert r.status_code == 200, r.text
    return np.asarray(r.json()["poses"])


def joint_limits(client, robot_id: str) -> tuple[np.ndarray, np.ndarray]:
    robots = {entry["id"]: entry for entry in client.get("/robots").json()}
    joints = robots[robot_id]["joints"]
    return (np.array([j["lower"] for j in joints]), np.array([j["upper"] for j in joints]))


# ---------------------------------------------------------------------------------------
# Forward kinematics


@pytest.mark.parametrize("q_deg, T_paper", GLT_FK)
def test_glt_fk_matches_paper_table2_and_eq14_16(ro_client, q_deg, T_paper):
    T = fk_poses(ro_client, GLT, rad(q_deg))[0]
    T_paper = np.asarray(T_paper)
    np.testing.assert_allclose(T[:3, 3], T_paper[:3, 3], atol=0.1)
    np.testing.assert_allclose(T[:3, :3], T_paper[:3, :3], atol=1e-3)
    np.testing.assert_allclose(T[3], [0, 0, 0, 1], atol=1e-12)


def test_glt_fk_batch_returns_one_pose_per_configuration(ro_client):
    q = [rad(q_deg) for q_deg, _ in GLT_FK]
    poses = fk_poses(ro_client, GLT, q)
    assert poses.shape == (3, 4, 4)
    for pose, (_, T_paper) in zip(poses, GLT_FK):
        np.testing.assert_allclose(pose[:3, 3], np.asarray(T_paper)[:3, 3], atol=0.1)
    # Batch and single calls agree.
    np.testing.assert_allclose(fk_poses(ro_client, GLT, q[1])[0], poses[1], atol=1e-9)


@pytest.mark.parametrize("robot_id, dof", [("glt_palletizer", 6), ("hyper_redundant_9dof", 9)])
def test_fk_all_frames(ro_client, robot_id, dof):
    q = np.random.default_rng(3).uniform(-1.0, 1.0, size=(4, dof))
    r = ro_client.post(f"/robots/{robot_id}/fk", json={"q": q.tolist(), "frames": "all"})
    assert r.status_code == 200, r.text
    body = r.json()
    poses, frames = np.asarray(body["poses"]), np.asarray(body["frames"])
    assert poses.shape == (4, 4, 4)
    assert frames.shape == (4, dof + 1, 4, 4)
    np.testing.assert_allclose(frames[:, -1], poses, atol=1e-9)
    base = np.asarray(ro_client.get(f"/robots/{robot_id}").json()["base"])
    np.testing.assert_allclose(frames[:, 0], np.broadcast_to(base, (4, 4, 4)), atol=1e-9)
    # Without "frames": "all" the same poses and no frames.
    r = ro_client.post(f"/robots/{robot_id}/fk", json={"q": q.tolist()})
    np.testing.assert_allclose(r.json()["poses"], poses, atol=1e-9)
    assert r.json().get("frames") is None


@pytest.mark.parametrize("q_deg, xy_mm", PILE_FK_XY)
def test_pile_driver_fk_xy_matches_paper(ro_client, q_deg, xy_mm):
    T = fk_poses(ro_client, PILE, rad(q_deg))[0]
    np.testing.assert_allclose(T[:2, 3], xy_mm, atol=0.5)


# ---------------------------------------------------------------------------------------
# Inverse kinematics


def test_glt_ik_of_printed_matrices_recovers_fk_input(ro_client):
    poses = [T for _, T in GLT_FK]
    r = ro_client.post(f"{GLT}/ik", json={"pose": poses, "all_solutions": True})
    assert r.status_code == 200, r.text
    results = r.json()["results"]
    assert len(results) == 3
    for (q_deg, _), res in zip(GLT_FK, results):
        assert res["success"] is True, res["message"]
        assert res["method"].startswith("analytic")
        sols = np.rad2deg(np.asarray(res["solutions"]))
        assert sols.ndim == 2 and sols.shape[1] == 6
        # The printed matrices are rounded to 4 decimals: 0.05 deg per joint.
        worst = np.abs(sols - np.asarray(q_deg, dtype=float)).max(axis=1)
        assert worst.min() < 0.05, f"{q_deg} not among {np.round(sols, 2).tolist()}"


def test_pile_driver_analytic_ik_roundtrip(ro_client):
    q = np.asarray(rad([50, 30, -20, -10, 5, 20]))
    T = fk_poses(ro_client, PILE, q)[0]
    r = ro_client.post(f"{PILE}/ik", json={"pose": T.tolist(), "method": "auto"})
    assert r.status_code == 200, r.text
    res = r.json()["results"][0]
    assert res["success"] is True, res["message"]
    assert res["method"] == "analytic:pile_driver"
    assert res["within_limits"] is True
    np.testing.assert_allclose(np.rad2deg(res["q"]), np.rad2deg(q), atol=0.01)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_hyper_redundant_numeric_ik(ro_client, seed):
    lower, upper = joint_limits(ro_client, "hyper_redundant_9dof")
    q = np.random.default_rng(seed).uniform(lower, upper)
    T = fk_poses(ro_client, HYPER, q)[0]
    r = ro_client.post(f"{HYPER}/ik", json={"pose": T.tolist(), "method": "numeric"})
    assert r.status_code == 200, r.text
    res = r.json()["results"][0]
    assert res["success"] is True, res["message"]
    assert res["method"] == "numeric"
    assert res["position_error"] < 1e-4
    q_ik = np.asarray(res["q"])
    assert q_ik.shape == (9,)
    assert np.all(q_ik >= lower - 1e-9) and np.all(q_ik <= upper + 1e-9)
    T_ik = fk_poses(ro_client, HYPER, q_ik)[0]
    assert np.linalg.norm(T_ik[:3, 3] - T[:3, 3]) < 1e-4
    np.testing.assert_allclose(T_ik[:3, :3], T[:3, :3], atol=1e-6)


def test_unreachable_pose_is_200_with_success_false(ro_client):
    T = np.eye(4)
    T[0, 3] = 5000.0
    r = ro_client.post(f"{GLT}/ik", json={"pose": T.tolist()})
    assert r.status_code == 200, r.text
    res = r.json()["results"][0]
    assert res["success"] is False
    assert res["q"] is None
    assert "unreachable" in res["message"].lower() or "reach" in res["message"].lower()


@pytest.mark.parametrize("robot_id", ["glt_palletizer", "hyper_redundant_9dof"])
def test_numeric_ik_of_absurdly_far_pose_is_not_a_server_error(ro_client, robot_id):
    """API.md: never 500 for anything a ro_client sends. A finite but huge target (1e308 mm)
    must give 422 or a result with success false."""
    T = np.eye(4)
    T[0, 3] = 1e308
    r = ro_client.post(f"/robots/{robot_id}/ik", json={"pose": T.tolist(), "method": "numeric"})
    assert r.status_code in (200, 422), r.text
    if r.status_code == 200:
        assert r.json()["results"][0]["success"] is False


# ---------------------------------------------------------------------------------------
# Jacobian


def skew_to_vector(S: np.ndarray) -> np.ndarray:
    return np.array([S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1]]) / 2


@pytest.mark.parametrize(
    "robot_id, q",
    [
        ("glt_palletizer", rad([15, 30, 45, 60, 90, 160])),
        ("pile_driver", rad([50, 30, -20, -10, 5, 20])),
        ("hyper_redundant_9dof", [0.3, -0.2, 0.5, 0.1, -0.4, 0.6, 0.2, -0.3, 0.7]),
    ],
)
def test_jacobian_matches_finite_differences(ro_client, robot_id, q):
    url = f"/robots/{robot_id}"
    q = np.asarray(q, dtype=float)
    dof = q.size
    r = ro_client.post(f"{url}/jacobian", json={"q": q.tolist()})
    assert r.status_code == 200, r.text
    body = r.json()
    J = np.asarray(body["jacobian"])
    assert J.shape == (6, dof)
    assert body["manipulability"] >= 0
    assert body["condition"] is None or body["condition"] >= 1 - 1e-9

    h = 1e-6
    steps = np.eye(dof) * h
    poses = fk_poses(ro_client, url, np.vstack([q + steps, q - steps]))
    plus, minus = poses[:dof], poses[dof:]
    J_lin = ((plus[:, :3, 3] - minus[:, :3, 3]) / (2 * h)).T
    np.testing.assert_allclose(J[:3], J_lin, atol=1e-3 * max(1.0, np.abs(J_lin).max()))
    # Angular rows: dR/dq_i R^T = skew(w_i).
    R = fk_poses(ro_client, url, q)[0][:3, :3]
    J_ang = np.array(
        [skew_to_vector((plus[i, :3, :3] - minus[i, :3, :3]) / (2 * h) @ R.T) for i in range(dof)]
    ).T
    np.testing.assert_allclose(J[3:], J_ang, atol=1e-5)


# ---------------------------------------------------------------------------------------
# Workspace


def test_pile_driver_workspace_ranges(ro_client):
    r = ro_client.post(f"{PILE}/workspace", json={"samples": 30000, "seed": 0})
    assert r.status_code == 200, r.text
    ws = r.json()
    assert ws["samples"] == 30000
    rmin, rmax = ws["radial"]
    vmin, vmax = ws["vertical"]
    assert 0 <= rmin < rmax
    assert 1800 <= rmax <= 1920
    assert -1000 <= vmin <= -700
    assert 1400 <= vmax <= 1510
    assert len(ws["points"]) == 20000
    points = np.asarray(ws["points"])
    assert points.shape == (20000, 3)
    assert np.all(points >= np.asarray(ws["min"]) - 1e-9)
    assert np.all(points <= np.asarray(ws["max"]) + 1e-9)
    assert ws["volume"] > 0


@pytest.mark.parametrize(
    "samples, return_points, expected", [(500, 50, 50), (40, 100, 40), (50, 0, 0)]
)
def test_workspace_return_points(ro_client, samples, return_points, expected):
    body = {"samples": samples, "seed": 1, "return_points": return_points}
    r = ro_client.post(f"{PILE}/workspace", json=body)
    assert r.status_code == 200, r.text
    assert len(r.json()["points"]) == expected


def test_workspace_same_seed_same_answer(ro_client):
    body = {"samples": 3000, "seed": 7, "return_points": 200}
    first = ro_client.post(f"{GLT}/workspace", json=body).json()
    second = ro_client.post(f"{GLT}/workspace", json=body).json()
    assert first == second
    other = ro_client.post(f"{GLT}/workspace", json={**body, "seed": 8}).json()
    assert other["points"] != first["points"]


# ---------------------------------------------------------------------------------------
# Errors: each case asserts the status and that ``detail`` names the field at fault.

EYE = np.eye(4).tolist()
NON_RIGID = (np.diag([2.0, 2.0, 2.0, 1.0])).tolist()
FAR = [[1, 0, 0, 5000], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]

ERROR_CASES = [
    pytest.param(f"{GLT}/fk", {"q": [0.0] * 5}, 422, "q", id="fk-q-too-short"),
    pytest.param(f"{GLT}/fk", {"q": [0.0] * 7}, 422, "q", id="fk-q-too-long"),
    pytest.param(f"{GLT}/fk", {"q": [[0.0] * 6, [0.0] * 5]}, 422, "q", id="fk-batch-row-short"),
    pytest.param(f"{GLT}/fk", '{"q":[0,0,0,0,0,NaN]}', 422, "q", id="fk-nan"),
    pytest.param(f"{GLT}/fk", '{"q":[0,0,0,0,0,Infinity]}', 422, "q", id="fk-inf"),
    pytest.param(f"{GLT}/fk", '{"q":[[0,0,0,0,0,0],[0,-Infinity,0,0,0,0]]}', 422, "q",
                 id="fk-batch-minus-inf"),
    pytest.param(f"{GLT}/fk", {"q": [0.0] * 6, "frames": "some"}, 422, "frames", id="fk-frames"),
    pytest.param(f"{GLT}/fk", {"q": [0.0] * 6, "qq": 1}, 422, "qq", id="fk-extra-field"),
    pytest.param(f"{GLT}/fk", {"q": [[0] * 6] * 100_001}, 413, "q", id="fk-too-many"),
    pytest.param(f"{GLT}/fk", {"q": [[0] * 6] * 10_001, "frames": "all"}, 413, "q",
                 id="fk-frames-too-many"),
    pytest.param("/robots/nope/fk", {"q": [0.0] * 6}, 404, "robot_id", id="fk-unknown-robot"),
    pytest.param(f"{GLT}/jacobian", {"q": [0.0] * 5}, 422, "q", id="jacobian-q-short"),
    pytest.param(f"{GLT}/jacobian", '{"q":[0,0,NaN,0,0,0]}', 422, "q", id="jacobian-nan"),
    pytest.param("/robots/nope/jacobian", {"q": [0.0] * 6}, 404, "robot_id",
                 id="jacobian-unknown-robot"),
    pytest.param(f"{GLT}/ik", {"pose": NON_RIGID}, 422, "pose", id="ik-non-rigid"),
    pytest.param(f"{GLT}/ik", {"pose": np.eye(3).tolist()}, 422, "pose", id="ik-pose-3x3"),
    pytest.param(f"{GLT}/ik", {"pose": np.eye(4)[:, :3].tolist()}, 422, "pose", id="ik-pose-4x3"),
    pytest.param(f"{GLT}/ik", {"pose": [EYE, np.eye(3).tolist()]}, 422, "pose",
                 id="ik-pose-batch-mixed"),
    pytest.param(f"{GLT}/ik", '{"pose":[[1,0,0,NaN],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}', 422,
                 "pose", id="ik-pose-nan"),
    pytest.param(f"{GLT}/ik", {"pose": EYE, "q0": [0.0] * 5}, 422, "q0", id="ik-q0-short"),
    pytest.param(f"{GLT}/ik", {"pose": EYE, "method": "foo"}, 422, "method", id="ik-method-foo"),
    pytest.param(f"{HYPER}/ik", {"pose": FAR, "method": "analytic"}, 422, "method",
                 id="ik-analytic-without-closed-form"),
    pytest.param(f"{GLT}/ik", {"pose": EYE, "method": "learned"}, 409, "method",
                 id="ik-learned-untrained"),
    pytest.param(f"{GLT}/ik", {"pose": EYE, "tolerance": 1}, 422, "tolerance",
                 id="ik-extra-field"),
    pytest.param("/robots/nope/ik", {"pose": EYE}, 404, "robot_id", id="ik-unknown-robot"),
    pytest.param(f"{PILE}/workspace", {"samples": 0}, 422, "samples", id="ws-samples-0"),
    pytest.param(f"{PILE}/workspace", {"samples": 2_000_001}, 413, "samples",
                 id="ws-samples-too-many"),
    pytest.param(f"{PILE}/workspace", {"samples": 10, "voxel": 0}, 422, "voxel", id="ws-voxel-0"),
    pytest.param(f"{PILE}/workspace", {"samples": 10, "return_points": -1}, 422,
                 "return_points", id="ws-return-points-negative"),
    pytest.param(f"{PILE}/workspace", {"samples": 10, "seed": -1}, 422, "seed",
                 id="ws-seed-negative"),
    pytest.param(f"{PILE}/workspace", {"samples": 10, "sample": 10}, 422, "sample",
                 id="ws-extra-field"),
    pytest.param("/robots/nope/workspace", {"samples": 10}, 404, "robot_id",
                 id="ws-unknown-robot"),
]


@pytest.mark.parametrize("url, body, status, field", ERROR_CASES)
def test_error_statuses_name_the_field(ro_client, url, body, status, field):
    if isinstance(body, str):
        r = ro_client.post(url, content=body, headers={"content-type": "application/json"})
    else:
        r = ro_client.post(url, json=body)
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    assert isinstance(detail, list) and detail
    assert names_field(detail, field), detail
    # The rejected input is not echoed back (a 100,000-row body would be).
    assert len(r.content) < 2000


def test_analytic_on_hyper_redundant_is_422_even_for_reachable_pose(ro_client):
    T = fk_poses(ro_client, HYPER, [0.1] * 9)[0]
    r = ro_client.post(f"{HYPER}/ik", json={"pose": T.tolist(), "method": "analytic"})
    assert r.status_code == 422
    assert names_field(r.json()["detail"], "method")


def test_viewer_show_without_viewer_is_503(ro_client):
    r = ro_client.post("/viewer/show", json={"robot": "glt_palletizer", "q": [0.0] * 6})
    assert r.status_code == 503
    assert r.json()["detail"]


def reject_constant(token: str):
    raise ValueError(f"non-standard JSON number {token}")


def test_unreachable_ik_answer_is_strict_json(ro_client):
    """Unreachable targets report null errors, never NaN/Infinity (not valid JSON)."""
    r = ro_client.post(f"{GLT}/ik", json={"pose": FAR})
    assert r.status_code == 200
    res = json.loads(r.text, parse_constant=reject_constant)["results"][0]
    for value in (res["position_error"], res["rotation_error"]):
        assert value is None or math.isfinite(value)


# ---------------------------------------------------------------------------------------
# Encodings: orjson answers are plain JSON, the .npy answers carry the same numbers.

NPY = {"accept": "application/x-npy"}


def npy_answer(r) -> np.ndarray:
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "application/x-npy"
    return np.load(io.BytesIO(r.content), allow_pickle=False)


def random_q(client, robot_id: str, n: int, seed: int = 3) -> np.ndarray:
    lower, upper = joint_limits(client, robot_id)
    return np.random.default_rng(seed).uniform(lower, upper, (n, len(lower)))


@pytest.mark.parametrize("n", [1, 7, 40])
def test_fk_npy_answer_equals_the_json_answer(ro_client, n):
    q = random_q(ro_client, "glt_palletizer", n)
    body = {"q": q.tolist() if n > 1 else q[0].tolist()}
    poses = npy_answer(ro_client.post(f"{GLT}/fk", json=body, headers=NPY))
    assert poses.dtype == np.float64 and poses.shape == (n, 4, 4)
    as_json = np.asarray(ro_client.post(f"{GLT}/fk", json=body).json()["poses"])
    np.testing.assert_array_equal(poses, as_json)  # JSON floats round-trip exactly


def test_fk_all_frames_npy_answer(ro_client):
    q = random_q(ro_client, "hyper_redundant_9dof", 5)
    body = {"q": q.tolist(), "frames": "all"}
    frames = npy_answer(ro_client.post(f"{HYPER}/fk", json=body, headers=NPY))
    assert frames.shape == (5, 9 + 1, 4, 4)
    answer = ro_client.post(f"{HYPER}/fk", json=body).json()
    np.testing.assert_array_equal(frames, answer["frames"])
    np.testing.assert_array_equal(frames[:, -1], answer["poses"])


def test_ik_npy_answer_is_the_best_solution_per_pose_with_nan_rows(ro_client):
    q = random_q(ro_client, "glt_palletizer", 3, seed=5)
    T = fk_poses(ro_client, GLT, q)
    body = {"pose": [*T.tolist(), FAR]}  # three reachable poses, one far out of reach
    rows = npy_answer(ro_client.post(f"{GLT}/ik", json=body, headers=NPY))
    results = ro_client.post(f"{GLT}/ik", json=body).json()["results"]
    assert rows.shape == (4, 6)
    for row, res in zip(rows, results):
        if res["q"] is None:
            assert np.isnan(row).all()
        else:
            np.testing.assert_array_equal(row, res["q"])
    assert not results[3]["success"] and np.isnan(rows[3]).all()
    assert all(r["success"] for r in results[:3])


def test_jacobian_and_workspace_npy_answers(ro_client):
    q = random_q(ro_client, "pile_driver", 1)[0].tolist()
    J = npy_answer(ro_client.post(f"{PILE}/jacobian", json={"q": q}, headers=NPY))
    np.testing.assert_array_equal(J, ro_client.post(f"{PILE}/jacobian", json={"q": q}).json()[
        "jacobian"])
    assert J.shape == (6, 6)
    body = {"samples": 2000, "seed": 4, "return_points": 300, "projections": False}
    points = npy_answer(ro_client.post(f"{PILE}/workspace", json=body, headers=NPY))
    assert points.shape == (300, 3)
    np.testing.assert_array_equal(points,
                                  ro_client.post(f"{PILE}/workspace", json=body).json()["points"])


def test_npy_is_only_sent_when_asked_for(ro_client):
    r = ro_client.post(f"{GLT}/fk", json={"q": [0.0] * 6}, headers={"accept": "*/*"})
    assert r.headers["content-type"] == "application/json" and r.json()["poses"]
    bad = ro_client.post(f"{GLT}/fk", json={"q": [0.0] * 5}, headers=NPY)
    assert bad.status_code == 422 and names_field(bad.json()["detail"], "q")  # errors: JSON


CALLS = [
    pytest.param(f"{GLT}/fk", {"q": [[0.1 * k] * 6 for k in range(12)]}, id="fk-batch"),
    pytest.param(f"{HYPER}/fk", {"q": [0.2] * 9, "frames": "all"}, id="fk-frames"),
    pytest.param(f"{GLT}/ik", {"pose": [EYE, FAR], "all_solutions": True}, id="ik"),
    pytest.param(f"{PILE}/jacobian", {"q": [0.1, 0.4, -0.5, 0.3, 0.2, 0.1]}, id="jacobian"),
    pytest.param(f"{PILE}/workspace", {"samples": 500, "return_points": 50}, id="workspace"),
]


@pytest.mark.parametrize("url, body", CALLS)
def test_orjson_answers_are_the_standard_librarys_json(ro_client, monkeypatch, url, body):
    """Strict JSON (no NaN or Infinity token), the same values as the standard library's
    encoder gives, and the same field order."""
    fast = ro_client.post(url, json=body)
    monkeypatch.setattr(responses, "legacy", True)
    slow = ro_client.post(url, json=body)
    assert fast.status_code == slow.status_code == 200
    assert fast.headers["content-type"] == "application/json"
    parsed = json.loads(fast.content, parse_constant=reject_constant)
    assert parsed == json.loads(slow.content, parse_constant=reject_constant)
    assert list(parsed) == list(json.loads(slow.content))


def test_dumps_writes_non_finite_numbers_as_null():
    out = responses.dumps({"a": np.array([1.5, np.nan, -np.inf]), "b": math.inf,
                           "c": np.float64(np.nan), "d": np.zeros((3, 4))[:, ::2],
                           "e": np.array([True, False]), "f": np.int64(7)})
    assert json.loads(out, parse_constant=reject_constant) == {
        "a": [1.5, None, None], "b": None, "c": None, "d": [[0.0, 0.0]] * 3,
        "e": [True, False], "f": 7}


def test_npy_bytes_round_trip():
    a = np.arange(24, dtype=float).reshape(2, 3, 4)[:, ::2]
    back = np.load(io.BytesIO(responses.npy_bytes(a)), allow_pickle=False)
    assert back.dtype == np.float64 and back.shape == (2, 2, 4)
    np.testing.assert_array_equal(back, a)


def test_bodies_orjson_refuses_are_read_as_before(ro_client):
    """A NaN token is not JSON: orjson refuses the body, the standard library reads it, and
    the answer is the same 422 naming the field as without orjson."""
    r = ro_client.post(f"{GLT}/fk", content='{"q":[0,0,0,0,0,NaN]}',
                    headers={"content-type": "application/json"})
    assert r.status_code == 422 and names_field(r.json()["detail"], "q")
    broken = ro_client.post(f"{GLT}/fk", content='{"q":[0,0,', headers={
        "content-type": "application/json"})
    assert broken.status_code == 422
    assert broken.json()["detail"][0]["type"] == "json_invalid"


def test_a_body_that_is_not_text_is_400_as_before(ro_client):
    r = ro_client.post(f"{GLT}/fk", content=b"\xbbUF\xa1",
                    headers={"content-type": "application/json"})
    assert r.status_code == 400 and r.json()["detail"][0]["type"] == "http_error"
    r = ro_client.post(f"{GLT}/ik", content=b"\xbbUF\xa1",
                    headers={"content-type": "application/json"})
    assert r.status_code == 400
