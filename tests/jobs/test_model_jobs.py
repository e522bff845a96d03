"""Jobs on robot models: calibration and learned-IK training, and what they unlock."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest

from app.jobs.model_kinds import DEFAULT_MAX_MEAN_POSITION_ERROR
from kinematics.fk import fk
from kinematics.library import builtin_model

from .conftest import wait_for

#: Paper 002's Table 3 hole, drilled along the face normal: the tunnel drilling arm's joints
#: (rad; mm for the telescope d3 and the feed d7).
TABLE_3_Q = np.radians([-46.77, -134.67, 0, 0, 134.67, 136.77, 0])
TABLE_3_Q[2], TABLE_3_Q[6] = 8486.38, 4022.0


def run_job(client, kind, **params):
    r = client.post("/jobs", json={"kind": kind, "params": params})
    assert r.status_code == 202, r.text
    job = wait_for(client, r.json()["id"], timeout=120)
    assert job["status"] == "succeeded", job
    return client.get(f"/jobs/{job['id']}/result").json()


@pytest.mark.slow
def test_calibrate_job_recovers_a_length(jobs_client):
    """Measurements from a GLT whose upper arm is 3 mm longer: the fit finds the 3 mm."""
    glt = builtin_model("glt_palletizer")
    data = glt.to_dict()
    data["joints"][2]["a"] += 3.0
    from kinematics.model import RobotModel

    truth = RobotModel.from_dict(data)
    q = np.random.default_rng(0).uniform(glt.lower, glt.upper, (15, 6))
    meas = [{"q": qk.tolist(), "pose": T.tolist()} for qk, T in zip(q, fk(truth, q))]
    out = run_job(jobs_client, "calibrate", robot="glt_palletizer", measurements=meas,
                  parameters=["joints[2].a"])
    assert abs(out["values"]["joints[2].a"] - (790.385 + 3.0)) < 1e-6
    assert out["rms_position"] < 1e-6 and out["success"]
    assert out["model"]["joints"][2]["a"] == out["values"]["joints[2].a"]


def test_calibrate_params_are_checked(jobs_client):
    bad = {"kind": "calibrate", "params": {"robot": "glt_palletizer",
                                           "measurements": [{"q": [0] * 6}],
                                           "parameters": ["joints[2].a"]}}
    r = jobs_client.post("/jobs", json=bad)
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"][:3] == ["body", "params", "measurements"]


@pytest.mark.slow
def test_learned_ik_trains_then_answers(jobs_client, capsys):
    """Paper 002 section 3.1 on the tunnel drilling arm: 10,000 samples, 8,800 / 1,200."""
    r = jobs_client.post("/robots/tunnel_drill_arm/ik",
                         json={"pose": np.eye(4).tolist(), "method": "learned"})
    assert r.status_code == 409  # nothing trained yet
    out = run_job(jobs_client, "ik_train", robot="tunnel_drill_arm", samples=10000,
                  test_fraction=0.12, seed=0)
    rep = out["report"]
    with capsys.disabled():
        print(f"\nlearned IK, tunnel_drill_arm, drilling posture, {rep['train']} train / "
              f"{rep['test']} test: max relative joint error "
              f"{100 * rep['max_relative_joint_error']:.3f} % of range (paper: 0.62 %), max "
              f"positioning error {rep['max_position_error']:.2f} mm (paper: 2.94 mm); after "
              f"numeric polishing {rep['polished_max_position_error']:.1e} mm")
    assert (rep["train"], rep["test"]) == (8800, 1200)
    assert rep["max_relative_joint_error"] < 0.0062
    assert rep["max_position_error"] < 2.94
    assert rep["polished_success"] == 1.0 and rep["polished_max_position_error"] < 1e-4
    # Validated on 1,000 poses of a stream of their own: far within the default gate.
    val = out["validation"]
    with capsys.disabled():
        print(f"validation on {val['samples']} held-out poses: position error mean "
              f"{val['mean_position_error']:.3f} mm, p95 {val['p95_position_error']:.3f} mm, "
              f"max {val['max_position_error']:.3f} mm (gate: mean <= "
              f"{val['max_mean_position_error']:g} mm)")
    assert out["quality"] == "ok" and val["samples"] == 1000
    assert val["max_mean_position_error"] == DEFAULT_MAX_MEAN_POSITION_ERROR
    assert val["mean_position_error"] < 0.5 and val["p95_position_error"] < 2.0
    assert val["max_rotation_error"] < 1e-9  # the drilling rule sets the orientation
    # Table 3's hole, drill along the face normal: the learned method answers.
    T = fk(builtin_model("tunnel_drill_arm"), TABLE_3_Q)
    res = jobs_client.post("/robots/tunnel_drill_arm/ik",
                           json={"pose": T.tolist(), "method": "learned"}).json()["results"][0]
    assert res["success"] and res["method"] == "learned+numeric"
    assert res["learned"]["position_error"] < 5.0
    assert res["position_error"] < 1e-4


@pytest.mark.slow
def test_learned_ik_on_the_glt_palletizer_fails_its_validation_with_defaults(jobs_client):
    """A free posture learns the orientation too, whose rotation columns obey quadratic
    identities; the map still fits (thin-plate spline), but it averages the arm's several
    joint solutions of one pose: off by about a metre, it fails its validation and is not
    served. With the gate raised, its guesses serve as starting points that polish to
    solutions."""
    out = run_job(jobs_client, "ik_train", robot="glt_palletizer")
    rep, val = out["report"], out["validation"]
    assert out["posture"] == "free" and (rep["train"], rep["test"]) == (8800, 1200)
    assert out["quality"] == "failed" and val["mean_position_error"] > 500
    assert val["p95_position_error"] >= val["mean_position_error"]
    assert val["max_position_error"] >= val["p95_position_error"]
    assert val["mean_rotation_error"] > 0.5  # rad: the orientation is off too
    assert "train again with more samples" in out["message"]
    model = builtin_model("glt_palletizer")
    T = fk(model, np.radians([15, 30, 45, 60, 90, 160]))
    r = jobs_client.post("/robots/glt_palletizer/ik", json={"pose": T.tolist(),
                                                             "method": "learned"})
    assert r.status_code == 409
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "method"]
    assert detail["msg"].startswith("the learned IK of robot 'glt_palletizer' (ik_train job ")
    assert "failed its validation: mean position error" in detail["msg"]
    assert f"{val['mean_position_error']:,.0f} mm > 10 mm" in detail["msg"]
    out = run_job(jobs_client, "ik_train", robot="glt_palletizer", samples=2000,
                  max_mean_position_error=5000)
    assert out["quality"] == "ok"
    assert out["report"]["polished_success"] > 0.95
    assert out["report"]["polished_max_position_error"] < 1e-3
    res = jobs_client.post("/robots/glt_palletizer/ik",
                           json={"pose": T.tolist(), "method": "learned"}).json()["results"][0]
    assert res["success"] and res["method"] == "learned+numeric"


@pytest.mark.slow
def test_a_tiny_training_fails_its_validation_and_the_learned_ik_refuses(jobs_client):
    """100 samples for an arm that reaches 18 m: the map's guesses are off by decimetres on
    poses it has not seen (on its own samples it interpolates them), so the job says so and
    the learned IK does not answer from it, until a training that passes replaces it."""
    pose = {"pose": fk(builtin_model("tunnel_drill_arm"), TABLE_3_Q).tolist(),
            "method": "learned"}
    out = run_job(jobs_client, "ik_train", robot="tunnel_drill_arm", samples=100, seed=3)
    val = out["validation"]
    assert out["quality"] == "failed"
    assert val["samples"] == 1000 and val["mean_position_error"] > 30
    assert out["message"].startswith(f"mean position error {val['mean_position_error']:.3g} "
                                     "mm > 10 mm (max_mean_position_error) on 1,000 held-out "
                                     "poses; train again with more samples")
    r = jobs_client.post("/robots/tunnel_drill_arm/ik", json=pose)
    assert r.status_code == 409
    assert "failed its validation: mean position error" in r.json()["detail"][0]["msg"]
    out = run_job(jobs_client, "ik_train", robot="tunnel_drill_arm", samples=2000, seed=3,
                  validation_samples=500)
    assert out["quality"] == "ok" and out["validation"]["samples"] == 500
    assert out["validation"]["mean_position_error"] < 2.0
    assert out["message"].startswith("mean position error ")
    r = jobs_client.post("/robots/tunnel_drill_arm/ik", json=pose)
    assert r.status_code == 200 and r.json()["results"][0]["success"]


def test_the_kernel_follows_the_features():
    from scipy.spatial.transform import Rotation

    from kinematics.learned_ik import distinct_rows, quadratic_tail_is_singular

    rng = np.random.default_rng(0)
    R = Rotation.random(500, random_state=1).as_matrix()
    position = rng.uniform(-1, 1, (500, 3))
    assert quadratic_tail_is_singular(np.hstack([position, R[:, :, 0], R[:, :, 1]]))
    assert not quadratic_tail_is_singular(position)
    X = np.array([[1.0, 2.0], [3.0, 4.0], [1.0, 2.0], [5.0, 6.0], [3.0, 4.0]])
    assert distinct_rows(X).tolist() == [0, 1, 3]


def test_duplicate_samples_do_not_break_the_map():
    """Two joint solutions of one pose are one feature row with two targets: the first is
    kept, and the map still answers."""
    from kinematics.learned_ik import LearnedIK

    rng = np.random.default_rng(0)
    features = rng.uniform(-1, 1, (200, 3))
    features[100:110] = features[:10]
    targets = rng.uniform(0, 1, (200, 3))
    learned = LearnedIK("x", features, targets, np.ones(3, bool), np.zeros(3),
                        np.zeros(3), np.ones(3))
    assert learned.kernel == "quintic"
    assert np.allclose(learned._interp(features[:10]), targets[:10], atol=1e-6)


# ---- which trained model answers ---------------------------------------------------------
def _ik_train_result(robot: str, seed: int, quality: str = "ok") -> tuple[str, np.ndarray]:
    """A valid ``ik_train`` result JSON for ``robot`` with a small map of its own, and the
    map's features (what tells two trained models apart); ``quality`` "failed": one whose
    validation found it a metre off."""
    from app.jobs.model_kinds import IKTrainResult
    from kinematics.learned_ik import LearnedIK

    rng = np.random.default_rng(seed)
    learned = LearnedIK(robot, rng.uniform(-1, 1, (30, 3)), rng.uniform(0, 1, (30, 3)),
                        np.ones(3, bool), np.zeros(3), np.zeros(3), np.ones(3))
    zero = 0.0
    report = {"samples": 30, "train": 24, "test": 6, "max_relative_joint_error": zero,
              "mean_relative_joint_error": zero, "per_joint": [zero] * 3,
              "max_position_error": zero, "mean_position_error": zero,
              "max_rotation_error": zero, "polished_max_position_error": zero,
              "polished_max_rotation_error": zero, "polished_success": 1.0}
    error = 1069.4 if quality == "failed" else 0.05
    validation = {"samples": 1000, "mean_position_error": error, "p95_position_error": error,
                  "max_position_error": error, "mean_rotation_error": zero,
                  "p95_rotation_error": zero, "max_rotation_error": zero,
                  "max_mean_position_error": 10.0}
    message = ("mean position error 1,069 mm > 10 mm (max_mean_position_error) on 1,000 "
               "held-out poses; train again with more samples" if quality == "failed"
               else "mean position error 0.05 mm ≤ 10 mm on 1,000 held-out poses")
    result = IKTrainResult(robot=robot, posture="free", fixed={}, report=report,
                           paper={"max_relative_joint_error": 0.0062,
                                  "max_position_error": 2.94},
                           validation=validation, quality=quality, message=message,
                           learned=learned.to_dict())
    return result.model_dump_json(), learned.features


@pytest.fixture
def manager(tmp_path):
    """A job manager on its own store, its backend not started: jobs are written directly."""
    from app.jobs.manager import JobManager
    from app.registry import RobotRegistry
    from app.store import Store

    store = Store(tmp_path / "jobs.sqlite3")
    return JobManager(store, RobotRegistry(store), "local", 1, 10)


def _finished(store, job_id: str, kind: str, robot: str, status: str = "succeeded",
              result: str | None = None) -> None:
    store.add_job(job_id, kind, {"robot": robot}, {})
    store.finish_job(job_id, status, result_json=result,
                     error=None if status == "succeeded" else "boom")


def _reads(store, monkeypatch) -> list[str]:
    """The ids of the jobs whose results are read from now on."""
    read: list[str] = []
    real = store.job_result

    def spy(job_id: str):
        read.append(job_id)
        return real(job_id)

    monkeypatch.setattr(store, "job_result", spy)
    return read


def test_a_second_trained_model_replaces_the_first(manager, monkeypatch):
    store = manager.store
    read = _reads(store, monkeypatch)
    assert manager.learned_ik("glt_palletizer") is None
    first, f1 = _ik_train_result("glt_palletizer", 1)
    _finished(store, "first", "ik_train", "glt_palletizer", result=first)
    job_id, learned = manager.learned_ik("glt_palletizer")
    assert job_id == "first" and np.array_equal(learned.features, f1)
    assert manager.learned_ik("glt_palletizer")[1] is learned  # cached: read once
    assert read == ["first"]
    second, f2 = _ik_train_result("glt_palletizer", 2)
    _finished(store, "second", "ik_train", "glt_palletizer", result=second)
    job_id, learned = manager.learned_ik("glt_palletizer")
    assert job_id == "second" and np.array_equal(learned.features, f2)
    assert read == ["first", "second"]


def test_deleting_the_served_training_hands_over_to_the_one_before_then_to_none(manager):
    store = manager.store
    for job_id, seed in (("first", 1), ("second", 2)):
        text, _ = _ik_train_result("glt_palletizer", seed)
        _finished(store, job_id, "ik_train", "glt_palletizer", result=text)
    assert manager.learned_ik("glt_palletizer")[0] == "second"
    assert manager.delete("second") is None  # ended: deleted, not cancelled
    assert manager.learned_ik("glt_palletizer")[0] == "first"
    assert manager.delete("first") is None
    assert manager.learned_ik("glt_palletizer") is None
    with pytest.raises(KeyError):
        manager.delete("first")


def test_a_model_that_failed_its_validation_is_refused_even_after_a_good_one(manager,
                                                                             monkeypatch):
    """The latest training is the one asked for: one that failed its validation is refused
    (the verdict cached as a model is), not stood in for by an older one that passed; so is
    a model stored before ``ik_train`` validated its models."""
    from app.jobs.model_kinds import LearnedIKRefused

    store = manager.store
    good, _ = _ik_train_result("glt_palletizer", 1)
    _finished(store, "good", "ik_train", "glt_palletizer", result=good)
    assert manager.learned_ik("glt_palletizer")[0] == "good"
    bad, _ = _ik_train_result("glt_palletizer", 2, quality="failed")
    _finished(store, "bad", "ik_train", "glt_palletizer", result=bad)
    read = _reads(store, monkeypatch)
    for _ in range(2):
        with pytest.raises(LearnedIKRefused) as info:
            manager.learned_ik("glt_palletizer")
        assert str(info.value) == (
            "the learned IK of robot 'glt_palletizer' (ik_train job bad) failed its "
            "validation: mean position error 1,069 mm > 10 mm (max_mean_position_error) on "
            "1,000 held-out poses; train again with more samples")
    assert read == ["bad"]
    unvalidated = json.loads(good)
    for key in ("validation", "quality", "message"):
        del unvalidated[key]
    _finished(store, "old", "ik_train", "glt_palletizer", result=json.dumps(unvalidated))
    with pytest.raises(LearnedIKRefused, match=r"\(ik_train job old\) was trained without "
                       "validation; train it again"):
        manager.learned_ik("glt_palletizer")
    again, features = _ik_train_result("glt_palletizer", 3)
    _finished(store, "again", "ik_train", "glt_palletizer", result=again)
    job_id, learned = manager.learned_ik("glt_palletizer")
    assert job_id == "again" and np.array_equal(learned.features, features)


def test_the_lookup_reads_no_other_kind_robot_or_status(manager, monkeypatch):
    """Newer jobs of another kind (with a result that is no ``ik_train`` result), for
    another robot (one whose id a pattern would match), or that failed, are passed over
    without reading their results; the query goes through an index."""
    store = manager.store
    text, features = _ik_train_result("glt_palletizer", 1)
    _finished(store, "trained", "ik_train", "glt_palletizer", result=text)
    _finished(store, "calibrated", "calibrate", "glt_palletizer", result='{"not": "ik"}')
    other, _ = _ik_train_result("glt_palletizer_2", 2)
    _finished(store, "other-robot", "ik_train", "glt_palletizer_2", result=other)
    _finished(store, "failed", "ik_train", "glt_palletizer", status="failed")
    read = _reads(store, monkeypatch)
    statements: list[str] = []
    real_open = store._open

    def traced(*args, **kwargs):
        conn = real_open(*args, **kwargs)
        conn.set_trace_callback(statements.append)
        return conn

    monkeypatch.setattr(store, "_open", traced)
    job_id, learned = manager.learned_ik("glt_palletizer")
    assert job_id == "trained" and np.array_equal(learned.features, features)
    assert read == ["trained"]
    # The look-up is one SELECT of at most one job that searches an index: it never lists
    # every job.
    selects = [s for s in statements if s.lstrip().upper().startswith("SELECT")
               and "FROM jobs" in s and "result_json" not in s]
    assert len(selects) == 1 and "LIMIT 1" in selects[0], statements
    with sqlite3.connect(store.path) as conn:
        plan = " | ".join(row[3] for row in conn.execute(f"EXPLAIN QUERY PLAN {selects[0]}"))
    assert "USING INDEX" in plan and "SCAN jobs" not in plan, plan
    assert manager.learned_ik("glt_palletiz%") is None
