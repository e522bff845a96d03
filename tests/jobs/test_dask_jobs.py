"""The same job kinds on a Dask distributed cluster (a LocalCluster in this process)."""

from __future__ import annotations

import os
import time

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app

from .conftest import wait_for

distributed = pytest.importorskip("distributed")


def local_cluster():
    """Two worker processes of one thread; the dashboard on a free port."""
    return distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                    dashboard_address="127.0.0.1:0", host="127.0.0.1")


@pytest.fixture(scope="module")
def cluster():
    with local_cluster() as c:
        yield c


@pytest.fixture
def dask_client(cluster, tmp_path):
    address = cluster.scheduler_address.removeprefix("tcp://")
    settings = Settings(no_viewer=True, data_dir=tmp_path, jobs_backend=f"dask://{address}")
    with TestClient(create_app(settings)) as client:
        yield client


def submit(client, kind, **params):
    r = client.post("/jobs", json={"kind": kind, "params": params})
    assert r.status_code == 202, r.text
    return r.json()["id"]


@pytest.mark.cluster
def test_health_names_the_backend(dask_client):
    assert dask_client.get("/health").json()["jobs_backend"].startswith("dask://")


@pytest.mark.cluster
def test_progress_and_result(dask_client):
    job_id = submit(dask_client, "sleep", seconds=2.0, steps=10)
    seen = []
    while (job := dask_client.get(f"/jobs/{job_id}").json())["status"] != "succeeded":
        assert job["status"] in ("queued", "running"), job
        seen.append(job["progress"])
        time.sleep(0.1)
    assert any(0 < p < 1 for p in seen)
    assert dask_client.get(f"/jobs/{job_id}/result").json()["slept"] == 2.0


@pytest.mark.cluster
def test_workspace_and_echo(dask_client):
    ws = submit(dask_client, "workspace", robot="glt_palletizer", samples=20000,
                return_points=10)
    echo = submit(dask_client, "echo", value={"a": [1, 2]})
    assert wait_for(dask_client, ws)["status"] == "succeeded"
    assert wait_for(dask_client, echo)["status"] == "succeeded"
    assert dask_client.get(f"/jobs/{echo}/result").json() == {"value": {"a": [1, 2]}}
    assert len(dask_client.get(f"/jobs/{ws}/result").json()["points"]) == 10


@pytest.mark.cluster
def test_failure_and_cancel(dask_client):
    bad = submit(dask_client, "sleep", seconds=0.1, outcome="raise")
    job = wait_for(dask_client, bad)
    assert job["status"] == "failed" and "asked to fail" in job["error"]
    long = submit(dask_client, "sleep", seconds=30, steps=300)
    wait_for(dask_client, long, statuses=("running",))
    time.sleep(0.5)
    t0 = time.monotonic()
    assert dask_client.delete(f"/jobs/{long}").status_code == 200
    assert wait_for(dask_client, long)["status"] == "cancelled"
    assert time.monotonic() - t0 < 2.0


@pytest.mark.cluster
def test_time_limit(dask_client):
    r = dask_client.post("/jobs", json={"kind": "sleep", "params": {"seconds": 30, "steps": 300},
                                        "time_limit_s": 1})
    assert r.status_code == 202, r.text
    job_id = r.json()["id"]
    wait_for(dask_client, job_id, statuses=("running",))
    t0 = time.monotonic()
    job = wait_for(dask_client, job_id, timeout=10)
    assert job["status"] == "failed" and job["error"] == "time limit of 1 s exceeded"
    assert time.monotonic() - t0 < 3.0
    # The cluster's thread is free again: the next job runs.
    assert wait_for(dask_client, submit(dask_client, "echo", value=5))["status"] == "succeeded"


@pytest.fixture
def fresh_cluster():
    """A cluster that has run nothing yet (the scheduler knows no task's duration)."""
    with local_cluster() as c:
        yield c


@pytest.mark.cluster
def test_one_job_spreads_over_both_workers(fresh_cluster, tmp_path, monkeypatch):
    """Also the first job of a cluster: its steps are not kept where its payload is."""
    from app.jobs.graph import run_inline
    from app.jobs.kinds import KINDS

    from . import graph_kinds
    from .test_job_graph_backends import overlapping

    monkeypatch.setitem(KINDS, graph_kinds.NAME, graph_kinds.KIND)
    address = fresh_cluster.scheduler_address.removeprefix("tcp://")
    settings = Settings(no_viewer=True, data_dir=tmp_path, jobs_backend=f"dask://{address}")
    with TestClient(create_app(settings)) as client:
        assert client.get("/health").json()["jobs"]["workers"] == 2
        # Parts of 3 s: a worker's first step also starts its step runner (a Python process
        # importing the kinds, 1-2 s on a loaded machine), which 1 s parts did not outlast.
        job_id = submit(client, graph_kinds.NAME, parts=4, part_s=3.0)
        job = wait_for(client, job_id, timeout=60)
        assert job["status"] == "succeeded", job
        assert job["attempts"] == 1
        result = client.get(f"/jobs/{job_id}/result").json()
    # The scheduler knows the parts' durations apart from the rest (the key's words).
    prefixes = fresh_cluster.scheduler.task_prefixes
    assert {"kinoplan-part", "kinoplan-merge", "kinoplan-payload"} <= set(prefixes)
    worker_pids = {p["ppid"] for p in result["parts"]}
    assert len(worker_pids) == 2 and os.getpid() not in worker_pids
    assert overlapping(result["parts"]) == 2
    params = graph_kinds.FanParams(parts=4, part_s=0.0)
    inline = run_inline(graph_kinds.graph(params), params, lambda f, m: None)
    assert result["total"] == inline.total


@pytest.mark.slow
def test_without_a_scheduler_jobs_answer_503_and_the_rest_works(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    settings = Settings(no_viewer=True, data_dir=tmp_path, jobs_backend=f"dask://127.0.0.1:{port}")
    with TestClient(create_app(settings)) as client:
        health = client.get("/health")
        assert health.status_code == 503
        jobs = health.json()["jobs"]
        assert jobs["ok"] is False and jobs["running"] is True and jobs["workers"] == 0
        assert f"tcp://127.0.0.1:{port} is unreachable" in jobs["error"]
        r = client.post("/jobs", json={"kind": "echo", "params": {"value": 1}})
        assert r.status_code == 503 and r.headers["retry-after"] == "5"
        assert "unreachable" in r.json()["detail"][0]["msg"]
        # Bad params are still named first.
        r = client.post("/jobs", json={"kind": "echo", "params": {"nope": 1}})
        assert r.status_code == 422
        r = client.post("/robots/glt_palletizer/fk", json={"q": [0, 0, 0, 0, 0, 0]})
        assert r.status_code == 200, r.text
        assert client.get("/jobs").status_code == 200


@pytest.mark.slow
def test_a_job_waiting_for_a_lost_scheduler_is_cancelled_at_once(tmp_path):
    """A cancel while the cluster is away ends the job (nothing of it runs then), and its
    time limit still counts; neither waits for the scheduler."""
    from app.jobs.dask_backend import DaskBackend, _Job
    from app.jobs.graph import whole
    from app.jobs.kinds import run_sleep
    from app.store import Store

    store = Store.in_data_dir(tmp_path)
    backend = DaskBackend(store, "tcp://127.0.0.1:1", 1, deadline_s=3600)
    for job_id, limit in (("a", None), ("b", 1.0)):
        store.add_job(job_id, "sleep", {}, {"params": {}}, time_limit_s=limit)
        record = store.claim_next_job()
        backend._jobs[job_id] = _Job(record.id, "sleep", {}, whole(run_sleep), limit,
                                     backend._deadline(limit))
    backend.cancel("a")
    backend._jobs["b"].deadline -= 2.0
    backend._pass()
    assert store.get_job("a").status == "cancelled"
    b = store.get_job("b")
    assert b.status == "failed" and b.error == "time limit of 1 s exceeded"
    assert backend._jobs == {} and backend.unavailable() is not None


def test_a_step_stopped_by_a_lost_scheduler_is_handed_over_not_cancelled(tmp_path,
                                                                          monkeypatch):
    """A step that stopped on its own (its worker lost the scheduler, nobody asked for a
    cancel) has its job handed to the cluster again; the record stays running."""
    from types import SimpleNamespace

    from app.jobs import dask_backend
    from app.jobs.dask_backend import DaskBackend, SchedulerLost, _Job
    from app.jobs.graph import whole
    from app.jobs.kinds import run_sleep
    from app.jobs.runner import StepCancelled
    from app.store import Store

    store = Store.in_data_dir(tmp_path)
    backend = DaskBackend(store, "tcp://127.0.0.1:1", 1)
    backend.client = SimpleNamespace(status="running", cancel=lambda futures: None)
    submitted = []
    monkeypatch.setattr(backend, "_submit", lambda job, again=False: submitted.append(again))
    monkeypatch.setattr(backend, "_signal_cancel", lambda job: None)
    for name, exc in (("j", StepCancelled("cancelled")), ("l", SchedulerLost("lost"))):
        store.add_job(name, "sleep", {}, {"params": {}})
        job = _Job(store.claim_next_job().id, "sleep", {}, whole(run_sleep), None, None)
        backend._jobs[name] = job
        backend._failed(job, SimpleNamespace(status="error", exception=lambda exc=exc: exc))
        assert submitted[-1] is True and store.get_job(name).status == "running"
    # An error of the step itself fails the job.
    store.add_job("k", "sleep", {}, {"params": {}})
    job = _Job(store.claim_next_job().id, "sleep", {}, whole(run_sleep), None, None)
    backend._jobs["k"] = job
    error = dask_backend.StepFailed("RuntimeError: boom")
    backend._failed(job, SimpleNamespace(status="error", exception=lambda: error))
    assert store.get_job("k").status == "failed" and store.get_job("k").error == \
        "RuntimeError: boom"


@pytest.mark.slow
def test_a_job_claimed_while_the_store_fails_is_handed_over_later(tmp_path, monkeypatch):
    from pathlib import Path

    from app.jobs.dask_backend import DaskBackend
    from app.store import Store, StoreError

    store = Store.in_data_dir(tmp_path)
    backend = DaskBackend(store, "tcp://127.0.0.1:1", 1)
    submitted = []
    monkeypatch.setattr(backend, "_submit", lambda job, again=False: submitted.append(job.id))
    store.add_job("a", "echo", {}, {"params": {"value": 1}})
    real = store.job_payload
    fail = [True]

    def flaky(job_id):
        if fail.pop() if fail else False:
            raise StoreError(Path("s"), "disk I/O error")
        return real(job_id)

    monkeypatch.setattr(store, "job_payload", flaky)
    with pytest.raises(StoreError):
        backend._start_jobs()
    assert store.get_job("a").status == "running" and submitted == []
    backend._start_jobs()
    assert submitted == ["a"] and store.get_job("a").attempts == 1


@pytest.mark.cluster
def test_jobs_leave_no_queues_on_the_scheduler(cluster, tmp_path):
    """However many jobs and supervisor passes, the scheduler holds one message queue (the
    service's), released when the service stops."""
    queues = cluster.scheduler.extensions["queues"]
    before = set(queues.queues)
    address = cluster.scheduler_address.removeprefix("tcp://")
    settings = Settings(no_viewer=True, data_dir=tmp_path, jobs_backend=f"dask://{address}")
    with TestClient(create_app(settings)) as client:
        ids = [submit(client, "sleep", seconds=0.5, steps=5) for _ in range(3)]
        ids.append(submit(client, "workspace", robot="glt_palletizer", samples=1_100_000,
                          return_points=10))  # two parts: several tasks of one job
        for job_id in ids:
            assert wait_for(client, job_id, timeout=60)["status"] == "succeeded"
        time.sleep(0.5)  # passes of the supervisor with nothing running
        assert len(set(queues.queues) - before) == 1
    deadline = time.monotonic() + 5
    while set(queues.queues) - before:
        assert time.monotonic() < deadline, set(queues.queues) - before
        time.sleep(0.05)


def test_steps_starting_at_once_make_the_worker_client_one_at_a_time(monkeypatch):
    """Two steps starting together on a fresh worker must not both make the worker's client
    (the race failed a step with an AssertionError inside Dask's connect)."""
    import threading

    import distributed

    from app.jobs import dask_backend

    inside, overlaps = [0], []
    guard = threading.Lock()

    def slow_get_client():
        with guard:
            inside[0] += 1
            overlaps.append(inside[0])
        time.sleep(0.05)
        with guard:
            inside[0] -= 1
        return "client"

    monkeypatch.setattr(distributed, "get_client", slow_get_client)
    threads = [threading.Thread(target=dask_backend.worker_client) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert overlaps == [1, 1, 1, 1]
