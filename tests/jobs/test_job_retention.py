"""No finished job fills the disk: a job's payload (an imported robot's meshes travel in it)
is dropped when the job ends, a finished job can be deleted, old finished jobs are pruned by
age and count (never queued or running ones, nor the learned IK the service serves), the
freed pages go back to the file system, and ``/health`` tells the store's size.

The payload of a motion job for an imported robot with meshes is the robot's description,
collision model and meshes (UR5: 4.79 MB, Panda: 1.64 MB); a test robot built here (a GLT
palletizer whose upper arm is a finely meshed box) carries a few hundred kB.
"""

from __future__ import annotations

import io
import json
import sqlite3
import time
import zipfile
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs import manager as manager_module
from app.jobs.manager import SERVED_KINDS, JobManager
from app.main import create_app
from app.registry import RobotRegistry
from app.store import _MIGRATIONS, COMPACT_MIN_FREE_BYTES, ENDED, STORE_FILENAME, Store

from .conftest import wait_for

#: A payload of the size of an imported robot's meshes.
BIG = {"params": {"value": 1}, "robot_files": {"mesh:arm": "x" * 1_000_000}}


def _rows(store: Store, job_id: str) -> tuple[int, str | None, int]:
    """(rows of the job, its ``jobs.payload_json``, its rows in ``job_payloads``), read
    from the file itself."""
    with sqlite3.connect(store.path) as conn:
        rows = conn.execute("SELECT payload_json FROM jobs WHERE id = ?", (job_id,)).fetchall()
        (payloads,) = conn.execute("SELECT COUNT(*) FROM job_payloads WHERE job_id = ?",
                                   (job_id,)).fetchone()
    return len(rows), rows[0][0] if rows else None, payloads


def _disk(path: Path) -> int:
    """Bytes of the database file at ``path`` with its write-ahead log emptied into it."""
    with sqlite3.connect(path) as conn:
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return path.stat().st_size


def _ended_at(store: Store, job_id: str, when: datetime) -> None:
    with sqlite3.connect(store.path) as conn:
        conn.execute("UPDATE jobs SET finished = ? WHERE id = ?",
                     (when.isoformat(timespec="microseconds"), job_id))


# ---- payloads ----------------------------------------------------------------------------
@pytest.mark.parametrize("end", ["succeeded", "failed", "cancelled", "cancelled while queued",
                                 "failed after restarts"])
def test_a_job_keeps_its_payload_while_it_can_run_and_drops_it_when_it_ends(tmp_path, end):
    store = Store(tmp_path / STORE_FILENAME)
    store.add_job("j", "echo", {"value": 1}, BIG)
    assert store.job_payload("j") == BIG and _rows(store, "j") == (1, "", 1)
    if end == "cancelled while queued":
        assert store.request_cancel("j").status == "cancelled"
    elif end == "failed after restarts":
        # Each restart queues the interrupted job again: it must still find its payload.
        for attempt in (1, 2, 3):
            assert store.claim_next_job().attempts == attempt
            assert store.job_payload("j") == BIG
            store.requeue_interrupted(max_attempts=3)
    else:
        store.claim_next_job()
        assert store.job_payload("j") == BIG  # running
        store.finish_job("j", end, result_json='{"value": 1}' if end == "succeeded" else None)
    job = store.get_job("j")
    assert job.status in ENDED and job.status in end
    assert _rows(store, "j") == (1, "", 0)
    with pytest.raises(KeyError):
        store.job_payload("j")


@pytest.mark.slow
def test_jobs_run_by_the_service_drop_their_payloads(jobs_client):
    c = jobs_client
    store = c.app.state.store
    ok = c.post("/jobs", json={"kind": "echo", "params": {"value": 1}}).json()["id"]
    bad = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 0.1,
                                                           "outcome": "raise"}}).json()["id"]
    stopped = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 30,
                                                               "steps": 300}}).json()["id"]
    wait_for(c, stopped, statuses=("running",))
    assert _rows(store, stopped) == (1, "", 1)
    c.delete(f"/jobs/{stopped}")
    assert [wait_for(c, j)["status"] for j in (ok, bad, stopped)] == [
        "succeeded", "failed", "cancelled"]
    for job_id in (ok, bad, stopped):
        assert _rows(store, job_id) == (1, "", 0)
    assert c.get(f"/jobs/{ok}/result").json() == {"value": 1}


def _meshed_arm_zip() -> bytes:
    """The GLT palletizer as URDF whose upper arm collides as a box meshed with 12,288
    triangles (a mesh file of 600 kB), zipped."""
    trimesh = pytest.importorskip("trimesh")
    from kinematics.library import builtin_model
    from kinematics.urdf import to_urdf

    text = to_urdf(builtin_model("glt_palletizer")).replace(
        '<link name="link_2" />',
        '<link name="link_2"><collision><geometry><mesh filename="meshes/upper.stl"/>'
        '</geometry></collision></link>')
    box = trimesh.creation.box(extents=(0.6, 0.15, 0.15))
    for _ in range(5):
        box = box.subdivide()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("arm/arm.urdf", text)
        z.writestr("arm/meshes/upper.stl", box.export(file_type="stl"))
    return buf.getvalue()


#: Motion jobs queued behind the two blockers: their payloads (some 400 kB each) add up to
#: more than the free pages the store gives back at once (COMPACT_MIN_FREE_BYTES, 16 MB).
#: The store's growth for 100 UR5 jobs (4.79 MB of payload each): benchmarks/bench_hardening.py
#: and docs/security.md.
QUEUED_JOBS = 50


@pytest.mark.slow
@pytest.mark.usefixtures("motion_kernels")
def test_finished_motion_jobs_grow_the_store_by_their_records_only(
        tmp_path, capsys, monkeypatch):
    """Queued, each motion job of an imported robot holds its meshes; once the jobs have
    succeeded the store is as big as before plus their records (params, results)."""
    n = QUEUED_JOBS
    # The compaction is the test's own, below, not the service's minutely one.
    monkeypatch.setattr(manager_module, "MAINTENANCE_EVERY_S", 3600.0)
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=2))) as c:
        store = c.app.state.store
        r = c.post("/robots/import", files={"file": ("arm.zip", _meshed_arm_zip(),
                                                     "application/zip")}, data={"id": "arm"})
        assert r.status_code == 201, r.text
        c.app.state.registry.collision_model("arm")  # built and stored (the import does it)
        # Both workers busy: the motion jobs wait in the queue, each with its payload.
        blockers = [c.post("/jobs", json={"kind": "sleep", "params": {
            "seconds": 300, "steps": 3000}}).json()["id"] for _ in range(2)]
        for job_id in blockers:
            wait_for(c, job_id, statuses=("running",))
        store.compact(0)
        base = _disk(store.path)
        ids = []
        for k in range(n):
            r = c.post("/jobs", json={"kind": "motion", "params": {
                "robot": "arm", "start": [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0],
                "goal": {"q": [-0.9, 0.3, -0.3 + 0.001 * k, 0.0, 0.5, 0.0]},
                "time_limit": 1.0, "trajectory": False, "seed": k}})
            assert r.status_code == 202, r.text
            ids.append(r.json()["id"])
        with sqlite3.connect(store.path) as conn:
            payloads = [n for (n,) in conn.execute(
                "SELECT LENGTH(payload_json) FROM job_payloads WHERE job_id IN "
                f"({', '.join('?' * len(ids))})", ids)]
        assert len(payloads) == n
        payload = sum(payloads) / n
        assert payload > 300_000  # the robot's meshes travel with each job
        assert _disk(store.path) - base > n * payload
        assert n * payload > 1.1 * COMPACT_MIN_FREE_BYTES  # or the store keeps its free pages
        for job_id in blockers:
            c.delete(f"/jobs/{job_id}")
        for job_id in ids:
            assert wait_for(c, job_id, timeout=300)["status"] == "succeeded"
        records = sum(len(store.job_result(j)) + len(json.dumps(store.get_job(j).params))
                      for j in ids)
        assert all(_rows(store, j) == (1, "", 0) for j in ids)
        pruned, freed = c.app.state.jobs.maintain()  # what the service does every minute
        assert pruned == 0 and freed > 0.9 * n * payload
        after = _disk(store.path)
        health = c.get("/health").json()["store"]
    # Each row also has its status, times and message, three index entries, and its share
    # of partly filled pages: well under 1 kB.
    assert after - base <= records + n * 1024, (after - base, records)
    assert health["job_counts"] == {"queued": 0, "running": 0, "succeeded": n,
                                    "failed": 0, "cancelled": 2}
    assert after <= health["bytes"] < base + 10 * payload
    with capsys.disabled():
        print(f"\nper finished motion job of a meshed arm: payload {payload / 1e3:.0f} kB "
              f"(what each kept before), store growth {(after - base) / n:.0f} B "
              f"(params and result: {records / n:.0f} B)")


# ---- older stores ------------------------------------------------------------------------
def _older_store(path, finished: int, payload_bytes: int) -> None:
    """A store as the service left it before payloads were dropped: ``finished`` ended jobs
    and one queued job, each with a payload of ``payload_bytes``."""
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA journal_mode=WAL")
    for migration in _MIGRATIONS[:4]:
        conn.executescript(migration)
    conn.execute("PRAGMA user_version = 4")
    payload = json.dumps({"params": {}, "robot_files": {"mesh:arm": "x" * payload_bytes}})
    for k in range(finished + 1):
        status = "queued" if k == finished else ENDED[k % 3]
        conn.execute(
            "INSERT INTO jobs (id, kind, params_json, payload_json, status, created, finished, "
            "result_json) VALUES (?, 'echo', '{\"value\": 1}', ?, ?, '2025-01-01', ?, ?)",
            (f"j{k}", payload, status, None if status == "queued" else "2025-01-01",
             '{"value": 1}' if status == "succeeded" else None))
    conn.commit()
    conn.close()


def test_an_older_store_drops_finished_payloads_and_shrinks_at_start(tmp_path, capsys):
    path = tmp_path / STORE_FILENAME
    _older_store(path, finished=30, payload_bytes=1_000_000)
    before = _disk(path)
    store = Store(path)  # migrates: the payloads of the finished jobs go at once
    assert store.job_payload("j30")["robot_files"]["mesh:arm"] == "x" * 1_000_000
    assert all(_rows(store, f"j{k}") == (1, "", 0) for k in range(30))
    assert store.get_job("j0").status == "succeeded"
    assert json.loads(store.job_result("j0")) == {"value": 1}
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA auto_vacuum").fetchone()[0] == 0  # an older file's mode
    # The service's start compacts it: once rewritten, later compactions are incremental.
    jobs = JobManager(store, RobotRegistry(store), "local", 1, 10)
    pruned, freed = jobs.maintain()
    after = _disk(path)
    assert pruned == 0 and freed > 0
    assert before > 30_000_000 and after < 2_000_000
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA auto_vacuum").fetchone()[0] == 2  # incremental
    assert jobs.maintain() == (0, 0)
    assert store.job_payload("j30")["robot_files"]["mesh:arm"] == "x" * 1_000_000
    with capsys.disabled():
        print(f"\nan older store of 30 finished jobs of 1 MB payloads: {before / 1e6:.1f} MB, "
              f"{after / 1e6:.2f} MB after its first start")


def test_compaction_waits_for_enough_free_pages_and_gives_them_back(tmp_path):
    store = Store(tmp_path / STORE_FILENAME)
    with sqlite3.connect(store.path) as conn:
        assert conn.execute("PRAGMA auto_vacuum").fetchone()[0] == 2  # a new store
    base = _disk(store.path)
    store.add_job("j", "echo", {"value": 1}, BIG)
    store.finish_job("j", "failed", error="boom")
    assert store.health() is None
    free = store.usage.free_bytes
    assert free > 900_000 and _disk(store.path) - base > 900_000
    assert store.compact() == 0  # below the threshold: kept for the next payloads
    assert _disk(store.path) - base > 900_000
    assert store.compact(min_free_bytes=0) > 900_000
    assert _disk(store.path) - base < 16_384
    store.health(max_age_s=0)
    assert store.usage.free_bytes == 0


# ---- DELETE ------------------------------------------------------------------------------
@pytest.mark.slow
def test_deleting_a_finished_job_frees_its_rows_and_then_it_is_gone(jobs_client):
    c = jobs_client
    store = c.app.state.store
    ok = c.post("/jobs", json={"kind": "echo", "params": {"value": 5}}).json()["id"]
    bad = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 0.1,
                                                           "outcome": "raise"}}).json()["id"]
    assert wait_for(c, ok)["status"] == "succeeded" and wait_for(c, bad)["status"] == "failed"
    assert c.get(f"/jobs/{ok}/plot").status_code == 422  # echo has no plot
    for job_id in (ok, bad):
        r = c.delete(f"/jobs/{job_id}")
        assert r.status_code == 204 and r.content == b""
        assert _rows(store, job_id) == (0, None, 0)
        for path in ("", "/result", "/plot"):
            r = c.get(f"/jobs/{job_id}{path}")
            assert r.status_code == 404 and r.json()["detail"][0]["loc"] == ["path", "job_id"]
        assert c.delete(f"/jobs/{job_id}").status_code == 404
    assert c.get("/jobs").json() == [] and c.get("/health").json()["store"]["job_counts"] == {
        "queued": 0, "running": 0, "succeeded": 0, "failed": 0, "cancelled": 0}


def test_delete_cancels_a_job_that_can_run_and_deletes_it_once_ended(tmp_path):
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1)
    with TestClient(create_app(settings)) as c:
        running = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 30,
                                                                   "steps": 300}}).json()["id"]
        queued = c.post("/jobs", json={"kind": "echo", "params": {"value": 1}}).json()["id"]
        wait_for(c, running, statuses=("running",))
        for job_id in (queued, running):
            r = c.delete(f"/jobs/{job_id}")  # cancelled (queued) or stopping (running)
            assert r.status_code == 200 and r.json()["id"] == job_id
            assert wait_for(c, job_id)["status"] == "cancelled"  # the record stays
            assert c.delete(f"/jobs/{job_id}").status_code == 204
            assert c.get(f"/jobs/{job_id}").status_code == 404


# ---- retention ---------------------------------------------------------------------------
def _jobs(tmp_path, **retention) -> JobManager:
    store = Store(tmp_path / STORE_FILENAME)
    return JobManager(store, RobotRegistry(store), "local", 1, 10, **retention)


def _ended(store: Store, job_id: str, status: str, when: datetime, kind: str = "echo",
           robot: str | None = None) -> None:
    store.add_job(job_id, kind, {"robot": robot} if robot else {}, BIG)
    store.claim_next_job()
    store.finish_job(job_id, status, result_json="{}" if status == "succeeded" else None)
    _ended_at(store, job_id, when)


def _waiting(store: Store) -> None:
    """A job running and one queued, both submitted long ago."""
    store.add_job("running", "sleep", {}, BIG)
    store.add_job("queued", "sleep", {}, BIG)
    store.claim_next_job()
    with sqlite3.connect(store.path) as conn:
        conn.execute("UPDATE jobs SET created = '2000-01-01', started = '2000-01-01'")


def test_retention_by_age_deletes_old_finished_jobs_only(tmp_path):
    jobs = _jobs(tmp_path, retention_days=7)
    store, now = jobs.store, datetime.now(UTC)
    _waiting(store)
    for k, status in enumerate(ENDED):
        _ended(store, f"old-{status}", status, now - timedelta(days=8, hours=k))
    _ended(store, "recent", "succeeded", now - timedelta(days=6))
    # The learned IK of a robot is served from its latest succeeded ik_train job: kept.
    _ended(store, "ik-before", "succeeded", now - timedelta(days=30), "ik_train", "arm")
    _ended(store, "ik-served", "succeeded", now - timedelta(days=20), "ik_train", "arm")
    _ended(store, "ik-failed", "failed", now - timedelta(days=10), "ik_train", "arm")
    assert jobs.maintain()[0] == 5
    assert {j.id for j in store.list_jobs()} == {"running", "queued", "recent", "ik-served"}
    assert store.job_payload("running") == store.job_payload("queued") == BIG
    assert "ik_train" in SERVED_KINDS and jobs.maintain()[0] == 0


def test_retention_by_count_keeps_the_jobs_that_ended_last(tmp_path):
    jobs = _jobs(tmp_path, retention_count=3)
    store, now = jobs.store, datetime.now(UTC)
    _waiting(store)
    # Submitted in one order, ended in the other: the three that ended last stay.
    for k in range(6):
        _ended(store, f"j{k}", ENDED[k % 3], now - timedelta(minutes=k))
    _ended(store, "ik-served", "succeeded", now - timedelta(days=1), "ik_train", "arm")
    assert jobs.maintain()[0] == 3
    assert {j.id for j in store.list_jobs()} == {"running", "queued", "j0", "j1", "j2",
                                                 "ik-served"}


def test_without_limits_nothing_is_pruned(tmp_path):
    jobs = _jobs(tmp_path)  # 0 days, 0 jobs: keep everything
    _waiting(jobs.store)
    for k in range(3):
        _ended(jobs.store, f"j{k}", "succeeded", datetime(2000, 1, 1, tzinfo=UTC))
    assert jobs.maintain() == (0, 0) and jobs.store.count_jobs() == 5


@pytest.mark.slow
def test_the_service_prunes_periodically(tmp_path, monkeypatch):
    monkeypatch.setattr(manager_module, "MAINTENANCE_EVERY_S", 0.1)
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1, job_retention_count=2)
    with TestClient(create_app(settings)) as c:
        done = [c.post("/jobs", json={"kind": "echo", "params": {"value": k}}).json()["id"]
                for k in range(4)]
        for job_id in done:
            wait_for(c, job_id)
        running = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 30,
                                                                   "steps": 300}}).json()["id"]
        queued = c.post("/jobs", json={"kind": "echo", "params": {"value": 9}}).json()["id"]
        wait_for(c, running, statuses=("running",))
        deadline = time.monotonic() + 10
        while c.get("/jobs").headers["X-Total-Count"] != "4" and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [j["id"] for j in c.get("/jobs").json()] == [*done[2:], running, queued]
        c.delete(f"/jobs/{running}")


def test_retention_defaults_are_finite_and_reach_the_manager(tmp_path):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path))
    assert (api.state.jobs.retention_days, api.state.jobs.retention_count) == (30.0, 10_000)
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, job_retention_days=0.5,
                              job_retention_count=0))
    assert (api.state.jobs.retention_days, api.state.jobs.retention_count) == (0.5, 0)
