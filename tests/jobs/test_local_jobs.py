"""The job API on the embedded local backend: progress, results, failures, cancel, limits."""

from __future__ import annotations

import os
import re
import signal
import threading
import time

import httpx
import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app

from .conftest import Service, wait_for


def submit(client, kind: str, **params) -> str:
    r = client.post("/jobs", json={"kind": kind, "params": params})
    assert r.status_code == 202, r.text
    body = r.json()
    assert body["status"] == "queued"
    return body["id"]


def test_progress_rises_then_result(jobs_client):
    job_id = submit(jobs_client, "sleep", seconds=1.5, steps=15)
    seen = []
    while True:
        job = jobs_client.get(f"/jobs/{job_id}").json()
        seen.append(job["progress"])
        if job["status"] == "succeeded":
            break
        assert job["status"] in ("queued", "running")
        time.sleep(0.05)
    assert seen == sorted(seen)  # never goes back
    assert len({p for p in seen if 0 < p < 1}) >= 3  # reported on the way
    assert job["progress"] == 1.0 and job["started"] and job["finished"]
    assert jobs_client.get(f"/jobs/{job_id}/result").json()["slept"] == 1.5
    assert job_id in [j["id"] for j in jobs_client.get("/jobs").json()]


@pytest.mark.slow
def test_result_is_409_until_succeeded(jobs_client):
    job_id = submit(jobs_client, "sleep", seconds=1.0)
    r = jobs_client.get(f"/jobs/{job_id}/result")
    assert r.status_code == 409 and "job_id" in r.json()["detail"][0]["loc"]
    wait_for(jobs_client, job_id)
    assert jobs_client.get(f"/jobs/{job_id}/result").status_code == 200


#: The pile driver's joint limits (paper 000, Table 1), rad.
PILE_DRIVER_LIMITS = np.array([(-np.pi, np.pi), (0, np.pi / 3), (-np.pi / 3, 0),
                               (-np.pi / 3, 0), (-np.pi / 6, np.pi / 6), (-np.pi, np.pi)])


def pile_driver_tool_points(q: np.ndarray) -> np.ndarray:
    """The pile driver's tool point ``(N, 3)`` mm in closed form, not through kinematics.fk:
    the swing turns a vertical plane in which the boom (pivot 200 mm out), stick and
    attachment (800, 600, 300 mm) form a planar chain whose tip sits 100 mm off its last
    link, at a right angle; the tilt and rotator do not move the point."""
    swing, boom, stick, four_bar = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    a3, a4 = boom + stick, boom + stick + four_bar
    out = 200 + 800 * np.cos(boom) + 600 * np.cos(a3) + 300 * np.cos(a4) - 100 * np.sin(a4)
    up = 800 * np.sin(boom) + 600 * np.sin(a3) + 300 * np.sin(a4) + 100 * np.cos(a4)
    return np.c_[out * np.cos(swing), out * np.sin(swing), up]


@pytest.mark.slow
def test_workspace_job_reports_the_seeded_monte_carlo(jobs_client):
    """The job's report, against the Monte Carlo redone here: 30,000 configurations drawn
    with ``default_rng(seed).uniform`` within Table 1's limits, tool points in closed form,
    and the 100 points returned drawn with ``default_rng(seed).choice`` in sampling order."""
    samples, seed = 30000, 3
    job_id = submit(jobs_client, "workspace", robot="pile_driver", samples=samples, seed=seed,
                    return_points=100)
    assert wait_for(jobs_client, job_id)["status"] == "succeeded"
    result = jobs_client.get(f"/jobs/{job_id}/result").json()
    lower, upper = PILE_DRIVER_LIMITS.T
    P = pile_driver_tool_points(np.random.default_rng(seed).uniform(lower, upper, (samples, 6)))
    assert result["samples"] == samples and result["seed"] == seed
    np.testing.assert_allclose(result["min"], P.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(result["max"], P.max(axis=0), atol=1e-9)
    radial = np.hypot(P[:, 0], P[:, 1])  # the base frame is the world frame here
    np.testing.assert_allclose(result["radial"], [radial.min(), radial.max()], atol=1e-9)
    np.testing.assert_allclose(result["vertical"], [P[:, 2].min(), P[:, 2].max()], atol=1e-9)
    picked = np.sort(np.random.default_rng(seed).choice(samples, size=100, replace=False))
    np.testing.assert_allclose(result["points"], P[picked], atol=1e-9)
    # The reach: 1600 mm of boom and stick plus the attachment's sqrt(300² + 100²) = 316 mm.
    assert 1900 < radial.max() <= 1600 + np.hypot(300, 100)
    # Volume: voxels of a 30th of the largest extent that hold a sample.
    voxel = float(np.max(P.max(axis=0) - P.min(axis=0))) / 30
    cells = {tuple(c) for c in np.floor((P - P.min(axis=0)) / voxel).astype(int)}
    assert result["voxel"] == pytest.approx(voxel, rel=1e-12)
    assert result["volume"] == pytest.approx(len(cells) * voxel**3, rel=1e-2)
    for name in ("xy", "xz", "yz"):
        assert np.sum(result["projections"][name]["counts"]) == samples, name


@pytest.mark.slow
def test_a_job_that_raises_fails_with_its_error(jobs_client):
    job_id = submit(jobs_client, "sleep", seconds=0.1, outcome="raise")
    job = wait_for(jobs_client, job_id)
    assert job["status"] == "failed" and "asked to fail" in job["error"]
    assert jobs_client.get(f"/jobs/{job_id}/result").status_code == 409


@pytest.mark.slow
def test_a_dying_worker_fails_only_its_job(jobs_client):
    dying = submit(jobs_client, "sleep", seconds=0.2, outcome="exit")
    fine = submit(jobs_client, "sleep", seconds=0.5)
    assert wait_for(jobs_client, dying)["status"] == "failed"
    assert "worker process died" in jobs_client.get(f"/jobs/{dying}").json()["error"]
    assert wait_for(jobs_client, fine)["status"] == "succeeded"
    # The pool keeps serving.
    assert wait_for(jobs_client, submit(jobs_client, "echo", value=1))["status"] == "succeeded"


@pytest.mark.slow
def test_a_worker_killed_mid_job(jobs_client):
    job_id = submit(jobs_client, "sleep", seconds=20, steps=200)
    pid = None
    while pid is None:
        m = re.search(r"pid (\d+)", jobs_client.get(f"/jobs/{job_id}").json()["message"])
        pid = int(m.group(1)) if m else None
        time.sleep(0.05)
    os.kill(pid, signal.SIGKILL)  # as the kernel's OOM killer would
    job = wait_for(jobs_client, job_id)
    assert job["status"] == "failed" and "signal 9" in job["error"]
    assert wait_for(jobs_client, submit(jobs_client, "echo", value=2))["status"] == "succeeded"


@pytest.mark.slow
def test_cancel_queued_and_running(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1)
    with TestClient(create_app(settings)) as client:
        # A first job starts the worker processes' server (not what this test measures).
        assert wait_for(client, submit(client, "echo", value=1))["status"] == "succeeded"
        running = submit(client, "sleep", seconds=30, steps=300)
        queued = submit(client, "sleep", seconds=30)
        wait_for(client, running, statuses=("running",))
        r = client.delete(f"/jobs/{queued}")
        assert r.status_code == 200 and r.json()["status"] == "cancelled"  # at once
        t0 = time.monotonic()
        assert client.delete(f"/jobs/{running}").status_code == 200
        job = wait_for(client, running)
        assert job["status"] == "cancelled" and time.monotonic() - t0 < 2.0
        # Again, once it has ended: deleted with its result; then, like an unknown job, 404.
        assert client.delete(f"/jobs/{running}").status_code == 204
        assert client.get(f"/jobs/{running}").status_code == 404
        assert client.delete(f"/jobs/{running}").status_code == 404
        assert client.delete("/jobs/nope").status_code == 404
        assert wait_for(client, submit(client, "echo", value=3))["status"] == "succeeded"


def test_queue_limit_answers_429(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1, max_queued_jobs=2)
    with TestClient(create_app(settings)) as client:
        first = submit(client, "sleep", seconds=30, steps=300)
        wait_for(client, first, statuses=("running",))
        submit(client, "sleep", seconds=1)
        submit(client, "sleep", seconds=1)
        r = client.post("/jobs", json={"kind": "sleep", "params": {"seconds": 1}})
        assert r.status_code == 429 and "queued" in r.json()["detail"][0]["msg"]
        for job in client.get("/jobs").json():
            if job["status"] in ("queued", "running"):
                client.delete(f"/jobs/{job['id']}")


@pytest.mark.parametrize(
    "payload, status, loc",
    [
        ({"kind": "nope"}, 422, ["body", "kind"]),
        ({"kind": "sleep", "params": {"seconds": -1}}, 422, ["body", "params", "seconds"]),
        ({"kind": "sleep", "params": {"sleep": 1}}, 422, ["body", "params", "sleep"]),
        ({"kind": "workspace", "params": {}}, 422, ["body", "params", "robot"]),
        ({"kind": "workspace", "params": {"robot": "nope"}}, 404, ["body", "params", "robot"]),
        ({"kind": "workspace", "params": {"robot": "pile_driver", "samples": 0}}, 422,
         ["body", "params", "samples"]),
        ({"params": {}}, 422, ["body", "kind"]),
    ],
)
def test_params_are_checked_before_queueing(jobs_client, payload, status, loc):
    before = len(jobs_client.get("/jobs").json())
    r = jobs_client.post("/jobs", json=payload)
    assert r.status_code == status, r.text
    assert r.json()["detail"][0]["loc"] == loc
    assert len(jobs_client.get("/jobs").json()) == before


def test_unknown_job_is_404(jobs_client):
    assert jobs_client.get("/jobs/nope").status_code == 404
    assert jobs_client.get("/jobs/nope/result").status_code == 404


def test_kinds_are_listed_with_their_params(jobs_client):
    kinds = {k["kind"]: k for k in jobs_client.get("/jobs/kinds").json()}
    assert {"sleep", "echo", "workspace"} <= set(kinds)
    assert "samples" in kinds["workspace"]["params"]["properties"]


def test_api_key_guards_state_changes(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, api_key="s3cret")
    with TestClient(create_app(settings)) as client:
        body = {"kind": "echo", "params": {"value": 1}}
        assert client.post("/jobs", json=body).status_code == 401
        wrong = {"Authorization": "Bearer nope"}
        assert client.post("/jobs", json=body, headers=wrong).status_code == 401
        good = {"Authorization": "Bearer s3cret"}
        job_id = client.post("/jobs", json=body, headers=good).json()["id"]
        assert client.get(f"/jobs/{job_id}").status_code == 200  # reading needs no key
        robot = {"id": "k", "joints": [{"lower": -1, "upper": 1}]}
        assert client.post("/robots", json=robot).status_code == 401
        assert client.post("/robots", json=robot, headers=good).status_code == 201
        assert client.delete("/robots/k").status_code == 401
        assert client.delete("/robots/k", headers=good).status_code == 204
        assert client.post("/viewer/show", json={"robot": "pile_driver"}).status_code == 401
        # Computations that change nothing stay open.
        assert client.post("/robots/pile_driver/fk", json={"q": [0] * 6}).status_code == 200


def test_request_body_cap_is_413(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, max_body_bytes=10_000)
    client = TestClient(create_app(settings))
    big = {"q": [[0.0] * 6] * 1000}
    r = client.post("/robots/pile_driver/fk", json=big)
    assert r.status_code == 413 and r.json()["detail"][0]["type"] == "too_large"


@pytest.mark.cluster
def test_sigkill_and_restart_lose_nothing(tmp_path):
    """Kill -9 the whole service mid-job: finished results survive, the interrupted job is
    queued again at the next start and runs to the end (our documented choice)."""
    svc = Service(tmp_path, "--workers", "1")
    try:
        done = httpx.post(svc.url + "/jobs", json={"kind": "echo", "params": {"value": 7}})
        done_id = done.json()["id"]
        client = httpx.Client(base_url=svc.url)
        wait_for(client, done_id)
        long_id = client.post("/jobs", json={"kind": "sleep",
                                             "params": {"seconds": 2, "steps": 20}}).json()["id"]
        wait_for(client, long_id, statuses=("running",))
        queued_id = client.post("/jobs", json={"kind": "echo",
                                               "params": {"value": 8}}).json()["id"]
        svc.kill()
    finally:
        svc.stop()
    svc = Service(tmp_path, "--workers", "1")
    try:
        client = httpx.Client(base_url=svc.url)
        assert client.get(f"/jobs/{done_id}/result").json() == {"value": 7}
        job = wait_for(client, long_id)
        assert job["status"] == "succeeded" and job["attempts"] == 2
        assert wait_for(client, queued_id)["status"] == "succeeded"
        assert client.get(f"/jobs/{queued_id}/result").json() == {"value": 8}
    finally:
        svc.stop()


@pytest.mark.cluster
def test_hundred_jobs_from_ten_clients(tmp_path):
    svc = Service(tmp_path, "--workers", "2")
    ids: list[list[str]] = [[] for _ in range(10)]
    try:
        def client_run(k: int) -> None:
            with httpx.Client(base_url=svc.url, timeout=30) as c:
                for i in range(10):
                    r = c.post("/jobs", json={"kind": "echo", "params": {"value": [k, i]}})
                    assert r.status_code == 202
                    ids[k].append(r.json()["id"])

        threads = [threading.Thread(target=client_run, args=(k,)) for k in range(10)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        flat = [j for per in ids for j in per]
        assert len(flat) == 100 and len(set(flat)) == 100
        client = httpx.Client(base_url=svc.url, timeout=30)
        for k, per in enumerate(ids):
            for i, job_id in enumerate(per):
                assert wait_for(client, job_id, timeout=120)["status"] == "succeeded"
                assert client.get(f"/jobs/{job_id}/result").json() == {"value": [k, i]}
        listed = [j["id"] for j in client.get("/jobs").json()]
        assert sorted(listed) == sorted(flat)  # none lost, none duplicated
    finally:
        svc.stop()



def test_a_new_job_is_answered_queued_even_when_a_worker_claims_it_at_once(tmp_path):
    """The record POST /jobs answers is the one written (status queued), whatever a busy
    supervisor does once the job is in the store (here: claims it the moment it can)."""
    from app.store import Store

    class EagerWorkerStore(Store):
        def get_job(self, job_id):
            self.claim_next_job()  # the supervisor gets in before any read
            return super().get_job(job_id)

    store = EagerWorkerStore.in_data_dir(tmp_path)
    assert store.add_job("j0", "echo", {}, {"params": {}}).status == "queued"
    assert store.get_job("j0").status == "running"
