"""Jobs on robot models: calibration and learned-IK training, and what they unlock."""

from __future__ import annotations

import numpy as np

from kinematics.fk import fk
from kinematics.library import builtin_model

from .conftest import wait_for


def run_job(client, kind, **params):
    r = client.post("/jobs", json={"kind": kind, "params": params})
    assert r.status_code == 202, r.text
    job = wait_for(client, r.json()["id"], timeout=120)
    assert job["status"] == "succeeded", job
    return client.get(f"/jobs/{job['id']}/result").json()


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
    # Table 3's hole, drill along the face normal: the learned method answers.
    model = builtin_model("tunnel_drill_arm")
    q = np.radians([-46.77, -134.67, 0, 0, 134.67, 136.77, 0])
    q[2], q[6] = 8486.38, 4022.0
    T = fk(model, q)
    res = jobs_client.post("/robots/tunnel_drill_arm/ik",
                           json={"pose": T.tolist(), "method": "learned"}).json()["results"][0]
    assert res["success"] and res["method"] == "learned+numeric"
    assert res["learned"]["position_error"] < 5.0
    assert res["position_error"] < 1e-4
