"""The ``tracking`` job kind: validation through the API (422s), the job function itself, a
tuned run through the job pool, and its plot."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs.tracking_kinds import MAX_RUNS, TrackingParams, run_tracking
from app.main import create_app
from kinematics.fk import fk
from kinematics.library import builtin_model

from .conftest import wait_for

LINE = {"kind": "line", "length": 100.0, "duration": 5.0}


@pytest.fixture
def client(tmp_path):
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))) as c:
        yield c


def submit(client, **params):
    return client.post("/jobs", json={"kind": "tracking", "params": params})


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"task": {"kind": "line", "length": -5.0}}, "length"),
        ({"task": {"kind": "line", "length": 5000.0}}, "length"),
        ({"task": {"kind": "ellipse", "radii": [150.0, 0.0]}}, "radii"),
        ({"task": {"kind": "ellipse", "duration": 0.0}}, "duration"),
        ({"task": {"kind": "circle"}}, "task"),
        ({"task": {"kind": "line", "direction": [1e300, 1e300, 0.0]}}, "direction"),
        ({"task": LINE, "tune": "hgso", "bounds": {"kp": [-1.0, 20.0]}}, "kp"),
        ({"task": LINE, "tune": "hgso", "bounds": {"ki": [50.0, 10.0]}}, "bounds"),
        ({"task": LINE, "controller": {"kind": "pi", "ki": -1.0}}, "ki"),
        ({"task": LINE, "tune": "hgso", "runs": MAX_RUNS + 1}, "runs"),
        ({"task": LINE, "runs": 3}, "params"),  # several runs without tuning are equal
        ({"task": LINE, "tune": "simplex"}, "tune"),
    ],
)
def test_bad_params_are_422_naming_the_field(checking_client, params, field):
    r = submit(checking_client, **params)
    assert r.status_code == 422, r.text
    assert field in str(r.json()["detail"]), r.text


def test_unknown_robot_is_404(client):
    assert submit(client, robot="nope", task=LINE).status_code == 404


def test_job_function_default_and_tuned_pi():
    base = {"robot": "hyper_redundant_9dof", "task": {**LINE, "direction": [0.48, 0.6, -0.64]},
            "iterations": 2}
    seen: list[float] = []
    default = run_tracking(TrackingParams(**base), lambda f, m: None).model_dump()
    tuned = run_tracking(TrackingParams(**base, controller={"kind": "pi"}, tune="gwo", runs=2),
                         lambda f, m: seen.append(f)).model_dump()
    for out in (default, tuned):
        assert len(out["q"]) == len(out["errors"]) == 51 and len(out["q"][0]) == 9
        assert out["joint_speed_max"] <= 0.1 + 1e-12
        assert out["max_error"] == pytest.approx(max(out["errors"]))
        # the desired tool path rides along, so a client (and the viewer) can draw both
        x_d = np.array(out["x_desired"])
        assert x_d.shape == (51, 3)
        assert np.linalg.norm(x_d[-1] - x_d[0]) == pytest.approx(LINE["length"])
        actual = fk(builtin_model("hyper_redundant_9dof"), np.array(out["q"]))[:, :3, 3]
        np.testing.assert_allclose(np.linalg.norm(x_d - actual, axis=1), out["errors"],
                                   atol=1e-9)
        np.testing.assert_allclose(out["x_actual"], actual, atol=1e-9)
    assert default["max_error"] < tuned["max_error"]
    assert len(tuned["runs"]) == 2 and [r["seed"] for r in tuned["runs"]] == [0, 1]
    assert tuned["summary"]["max"] >= tuned["max_error"]
    assert seen == sorted(seen) and seen[-1] == 1.0


def test_a_tuned_run_through_the_job_pool(client):
    r = submit(client, task=LINE, controller={"kind": "pi"}, tune="hgso", iterations=2,
               runs=2, seed=3)
    assert r.status_code == 202, r.text
    job = wait_for(client, r.json()["id"], timeout=120)
    assert job["status"] == "succeeded", job["error"]
    out = client.get(f"/jobs/{job['id']}/result").json()
    assert out["tune"] == "hgso" and len(out["runs"]) == 2
    assert out["mean_error"] <= out["max_error"] and len(out["kp"]) == 2


PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _png_shape(content: bytes) -> tuple[int, ...]:
    import io

    from matplotlib.image import imread

    return imread(io.BytesIO(content), format="png").shape


@pytest.mark.slow
def test_plot_of_a_tracking_job_even_after_its_robot_is_deleted(client):
    data = builtin_model("hyper_redundant_9dof").to_dict()
    data["id"] = "snake_copy"
    assert client.post("/robots", json=data).status_code == 201
    r = submit(client, robot="snake_copy", task=LINE)
    job = wait_for(client, r.json()["id"], timeout=60)
    assert job["status"] == "succeeded", job["error"]
    r = client.get(f"/jobs/{job['id']}/plot")
    assert r.status_code == 200, r.text
    assert r.headers["content-type"] == "image/png" and r.content[:8] == PNG_MAGIC
    assert _png_shape(r.content)[:2] == (900, 800)  # four stacked panels, 8 x 9 in at 100 dpi
    assert client.delete("/robots/snake_copy").status_code == 204
    r2 = client.get(f"/jobs/{job['id']}/plot")  # the stored result still plots
    assert r2.status_code == 200 and r2.content[:8] == PNG_MAGIC


def test_plot_errors_name_the_job(client):
    r = client.get("/jobs/nope/plot")
    assert r.status_code == 404 and "nope" in r.text
    # a long tuning run: not succeeded yet, so no plot (409), then cancelled
    r = submit(client, task=LINE, controller={"kind": "pi"}, tune="hgso", runs=10)
    job_id = r.json()["id"]
    r = client.get(f"/jobs/{job_id}/plot")
    assert r.status_code == 409 and "job_id" in str(r.json()["detail"])
    client.delete(f"/jobs/{job_id}")
    # a kind without a plot
    r = client.post("/jobs", json={"kind": "workspace",
                                   "params": {"robot": "glt_palletizer", "samples": 200}})
    job = wait_for(client, r.json()["id"], timeout=60)
    assert job["status"] == "succeeded", job["error"]
    r = client.get(f"/jobs/{job['id']}/plot")
    assert r.status_code == 422 and "workspace" in r.text and "tracking" in r.text


def test_plot_of_a_result_stored_before_the_paths_were_kept_says_so(tmp_path):
    from app.store import Store

    store = Store.in_data_dir(tmp_path)
    store.add_job("old", "tracking", {"robot": "hyper_redundant_9dof"}, {})
    old = {"robot": "hyper_redundant_9dof", "task": LINE, "controller": "pi", "tune": None,
           "t": [0.0, 0.1], "q": [[0.0] * 9] * 2, "errors": [0.0, 0.1]}
    store.finish_job("old", "succeeded", result_json=json.dumps(old))
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))) as c:
        r = c.get("/jobs/old/plot")
        assert r.status_code == 422 and "run the job again" in r.text
        assert c.get("/jobs/old/result").json() == old  # the stored result is untouched
