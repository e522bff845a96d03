"""The Dask backend under faults, with real processes: a ``dask scheduler`` and two
``dask worker`` commands (``tests/jobs/cluster.py``) and the service in this process.

A lost scheduler: the service keeps answering (FK 200, job submissions 503 with Retry-After,
``/health`` 503), keeps its jobs, runs them again once a scheduler is back at the address, or
fails them naming it after ``cluster_deadline_s``. A service started before its scheduler
connects when it appears. A killed worker: its job ends on another worker. A cancel: the
worker's CPU is free at once.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Iterator

import pytest

distributed = pytest.importorskip("distributed")
psutil = pytest.importorskip("psutil")

from fastapi.testclient import TestClient  # noqa: E402

from app.config import Settings  # noqa: E402
from app.main import create_app  # noqa: E402

from .cluster import DASK, Cluster, cpu_by_process, descendants, hang_guard, wait_gone  # noqa: E402
from .conftest import wait_for  # noqa: E402

pytestmark = [pytest.mark.cluster,
              pytest.mark.skipif(not DASK.exists(), reason=f"no {DASK} command")]

ROBOT = "glt_palletizer"
FK = {"q": [0.1, -0.2, 0.3, 0.0, 0.4, -0.1]}
#: CPU seconds a worker (process and children) may use in a 0.5 s window and count as idle
#: (an idle one uses 0.00-0.02 s; a busy one 0.5 s, down to some 0.1 s on a loaded machine).
IDLE_CPU_S = 0.05
#: Longest a test may run before its cluster is killed and the run interrupted.
HANG_S = 300.0


@pytest.fixture(scope="module")
def cluster(tmp_path_factory) -> Iterator[Cluster]:
    c = Cluster(tmp_path_factory.mktemp("dask-cluster"), workers=2)
    try:
        c.start()
        yield c
    finally:
        c.close()


@pytest.fixture(autouse=True)
def healthy(cluster) -> Iterator[None]:
    """Every test starts on a whole cluster (what the test before killed is back) and may not
    hang the run."""
    cluster.ensure()
    with hang_guard(HANG_S, cluster.close, cluster.workdir / "hang-stacks.txt"):
        yield


@contextlib.contextmanager
def serve(cluster: Cluster, data_dir, **settings) -> Iterator[TestClient]:
    """The service, its jobs on ``cluster``'s scheduler address."""
    app = create_app(Settings(no_viewer=True, data_dir=data_dir,
                              jobs_backend=f"dask://127.0.0.1:{cluster.port}", **settings))
    with TestClient(app) as client:
        yield client


def submit(client, kind: str, **params) -> str:
    r = client.post("/jobs", json={"kind": kind, "params": params})
    assert r.status_code == 202, r.text
    return r.json()["id"]


def jobs_of(client, ids) -> dict[str, dict]:
    return {i: client.get(f"/jobs/{i}").json() for i in ids}


def wait_started(client, ids, n: int, timeout: float = 60.0) -> list[str]:
    """The ids of ``n`` jobs running on a worker (status running, progress reported)."""
    deadline = time.monotonic() + timeout
    while True:
        jobs = jobs_of(client, ids)
        started = [i for i, j in jobs.items() if j["status"] == "running" and j["progress"] > 0]
        if len(started) >= n:
            return started[:n]
        seen = {i: (j["status"], j["progress"], j.get("error")) for i, j in jobs.items()}
        assert all(j["status"] in ("queued", "running") for j in jobs.values()), \
            f"a job ended before {n} ran at once: {seen}"
        assert time.monotonic() < deadline, f"{n} jobs did not start at once: {seen}"
        time.sleep(0.05)


def wait_health(client, status: int, timeout: float = 30.0) -> dict:
    deadline = time.monotonic() + timeout
    while (r := client.get("/health")).status_code != status:
        assert time.monotonic() < deadline, f"/health still {r.status_code}: {r.text}"
        time.sleep(0.1)
    return r.json()


def assert_submissions_refused(client) -> None:
    """POST /jobs: 503, a JSON error and Retry-After; a synchronous endpoint still works."""
    r = client.post("/jobs", json={"kind": "sleep", "params": {"seconds": 0.1}})
    assert r.status_code == 503, r.text
    assert r.headers["content-type"].startswith("application/json")
    assert r.json()["detail"], r.text
    assert int(r.headers["retry-after"]) > 0
    fk = client.post(f"/robots/{ROBOT}/fk", json=FK)
    assert fk.status_code == 200, fk.text
    assert len(fk.json()["poses"]) == 1


def assert_unreachable(health: dict, cluster: Cluster) -> None:
    assert health["status"] == "degraded" and health["jobs"]["ok"] is False, health
    error = health["jobs"]["error"]
    assert "unreachable" in error and f"127.0.0.1:{cluster.port}" in error, error


def test_jobs_outlive_a_killed_scheduler_and_run_again(cluster, tmp_path):
    """kill -9 of the scheduler with two jobs running and two queued: the service answers on,
    the jobs wait and all succeed once a scheduler is back; the running ones ran twice."""
    with serve(cluster, tmp_path) as client:
        ids = [submit(client, "sleep", seconds=5.0, steps=50) for _ in range(4)]
        started = wait_started(client, ids, 2)
        cluster.kill_scheduler()

        assert_unreachable(wait_health(client, 503), cluster)
        assert_submissions_refused(client)
        # The outage lasts; the jobs wait: none cancelled, failed or dropped.
        until = time.monotonic() + 3.0
        while time.monotonic() < until:
            for i, job in jobs_of(client, ids).items():
                expected = ("running",) if i in started else ("queued", "running")
                assert job["status"] in expected, job
            time.sleep(0.2)

        cluster.start_scheduler()  # app.worker starts its dask worker again: they join
        jobs = {i: wait_for(client, i, timeout=120) for i in ids}
        assert [j["status"] for j in jobs.values()] == ["succeeded"] * 4, jobs
        for i in started:
            assert jobs[i]["attempts"] >= 2, jobs[i]
        assert wait_health(client, 200)["jobs"]["ok"] is True
    assert cluster.workers_alive(), "a worker command ended with its scheduler"


def test_service_started_before_its_scheduler_connects_when_it_appears(cluster, tmp_path):
    """No scheduler at the start: the service starts anyway (degraded) and connects later."""
    cluster.kill_scheduler()
    with serve(cluster, tmp_path) as client:
        assert_unreachable(wait_health(client, 503, timeout=10), cluster)
        assert_submissions_refused(client)

        cluster.start_scheduler()
        assert wait_health(client, 200, timeout=60)["jobs"]["ok"] is True
        job = wait_for(client, submit(client, "sleep", seconds=0.5, steps=5), timeout=60)
        assert job["status"] == "succeeded", job


def test_job_of_a_killed_worker_ends_on_another(cluster, tmp_path):
    """kill -9 of the worker process (not its nanny) running a job: the job's process goes
    with it, and the job runs again elsewhere and succeeds."""
    with serve(cluster, tmp_path) as client:
        job_id = submit(client, "sleep", seconds=6.0, steps=60)
        wait_started(client, [job_id], 1)
        _, pid = cluster.worker_running(job_id)
        work = [psutil.Process(pid), *descendants(pid)]
        os.kill(pid, signal.SIGKILL)
        # The job's process dies with its worker: no orphan computes on.
        left = wait_gone(work, timeout=5)
        assert left == [], f"still alive after their worker was killed: {left}"

        job = wait_for(client, job_id, timeout=120)
        assert job["status"] == "succeeded" and job["attempts"] >= 2, job
        ran_in = client.get(f"/jobs/{job_id}/result").json()["pid"]
        assert ran_in not in {p.pid for p in work}


def worker_cpu(pids: dict[str, int], window: float = 0.5) -> dict[str, dict[str, float]]:
    """``{worker address: {process: CPU seconds}}`` of each worker's process and children in
    one common ``window``."""
    used = cpu_by_process(pids.values(), window)
    return {address: used[pid] for address, pid in pids.items()}


def most(usage: dict[str, dict[str, float]]) -> float:
    """The CPU seconds of the busiest worker."""
    return max(sum(procs.values()) for procs in usage.values())


def test_cancel_frees_the_worker_cpu_at_once(cluster, tmp_path):
    """A long workspace job cancelled: within 2 s no worker (process and children) uses CPU."""
    pids = cluster.worker_pids()
    deadline = time.monotonic() + 30
    while most(worker_cpu(pids)) >= IDLE_CPU_S:  # what a test before left is done
        assert time.monotonic() < deadline, "the workers do not go idle"
    with serve(cluster, tmp_path) as client:
        job_id = submit(client, "workspace", robot=ROBOT, samples=6_000_000, return_points=10)
        wait_started(client, [job_id], 1)
        deadline = time.monotonic() + 60
        while most(worker_cpu(pids)) < 2 * IDLE_CPU_S:  # it computes: the test can fail
            assert time.monotonic() < deadline, "the workspace job uses no CPU"
        sent = time.monotonic()
        assert client.delete(f"/jobs/{job_id}").status_code == 200
        windows = []  # (start after the cancel, CPU of each worker's processes in the window)
        while True:  # a quiet window must start within 2 s of the cancel
            start = time.monotonic() - sent
            assert start <= 2.0, f"workers still busy 2 s after the cancel: {windows}"
            used = worker_cpu(pids)
            windows.append((round(start, 2), used))
            if most(used) < IDLE_CPU_S:
                break
        assert wait_for(client, job_id, timeout=10)["status"] == "cancelled"
        later = worker_cpu(pids, 1.0)
        assert most(later) < 2 * IDLE_CPU_S, f"the work came back: {later}"


def test_cancel_stops_a_step_that_never_reports(cluster, tmp_path):
    """One 30 s sleep, no progress on the way: a cancel ends it, and frees its worker's
    thread, at once."""
    with serve(cluster, tmp_path) as client, cluster.client() as dask:
        job_id = submit(client, "sleep", seconds=30.0, steps=1)
        wait_for(client, job_id, statuses=("running",))
        pids = cluster.worker_pids(dask)
        deadline = time.monotonic() + 60
        # In its sleep: a task runs, and no worker computes (any start-up is over).
        while not any(cluster.executing(dask).values()) or most(worker_cpu(pids)) >= IDLE_CPU_S:
            assert time.monotonic() < deadline, "the job's step does not start"
        sent = time.monotonic()
        assert client.delete(f"/jobs/{job_id}").status_code == 200
        assert wait_for(client, job_id, timeout=10)["status"] == "cancelled"
        assert time.monotonic() - sent < 2.0
        while any((tasks := cluster.executing(dask)).values()):
            assert time.monotonic() - sent < 2.0, f"still running after the cancel: {tasks}"
            time.sleep(0.1)


def test_jobs_fail_naming_the_scheduler_after_the_cluster_deadline(cluster, tmp_path):
    """A scheduler lost for good: the jobs wait for it up to cluster_deadline_s, then fail
    naming it (never 'cancelled')."""
    with serve(cluster, tmp_path, cluster_deadline_s=3) as client:
        ids = [submit(client, "sleep", seconds=8.0, steps=80) for _ in range(3)]
        wait_started(client, ids, 2)
        cluster.kill_scheduler()
        lost = time.monotonic()
        while time.monotonic() - lost < 2.0:  # waiting for the scheduler, up to the deadline
            jobs = jobs_of(client, ids)
            assert all(j["status"] in ("queued", "running") for j in jobs.values()), jobs
            time.sleep(0.2)
        for i in ids:
            job = wait_for(client, i, timeout=30)
            assert job["status"] == "failed", job
            assert "unreachable" in job["error"], job["error"]
            assert f"127.0.0.1:{cluster.port}" in job["error"], job["error"]
