"""An unusable store (deleted, corrupt, read-only, disk full): /health, 503s, the job loop's
back-off and recovery, and a clean exit at start-up."""

from __future__ import annotations

import logging
import os
import shutil
import socket
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from fastapi.testclient import TestClient

import app.jobs.backend as backend_module
from app.__main__ import main
from app.api.routes import health as health_route
from app.config import Settings
from app.jobs.backend import SupervisedBackend
from app.main import create_app
from app.store import STORE_FILENAME, Store, StoreError

REPO = Path(__file__).resolve().parents[2]

ARM = {
    "id": "two_link", "name": "Two links", "convention": "mdh",
    "joints": [
        {"name": "j1", "type": "revolute", "a": 0, "alpha": 0, "d": 0, "lower": -3, "upper": 3},
        {"name": "j2", "type": "revolute", "a": 500, "alpha": 0, "d": 0, "lower": -3,
         "upper": 3},
    ],
}


@pytest.fixture
def client(tmp_path, monkeypatch) -> TestClient:
    """An app without its job backend running; every /health checks the store afresh."""
    monkeypatch.setattr(health_route, "HEALTH_TTL_S", 0.0)
    return TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path)))


def store_of(client: TestClient) -> Store:
    return client.app.state.store


def submit(client: TestClient, value=1) -> str:
    r = client.post("/jobs", json={"kind": "echo", "params": {"value": value}})
    assert r.status_code == 202, r.text
    return r.json()["id"]


def assert_store_503(r, *words: str) -> None:
    assert r.status_code == 503, (r.status_code, r.text)
    (entry,) = r.json()["detail"]
    assert entry["loc"] == ["service", "store"] and entry["type"] == "unavailable"
    assert entry["msg"].startswith("the data store is unavailable: ")
    for word in words:
        assert word in entry["msg"], entry["msg"]
    assert r.headers["retry-after"] == "5"


def assert_health(client: TestClient, store_error: str | None) -> dict:
    r = client.get("/health")
    body = r.json()
    if store_error is None:
        assert r.status_code == 200, body
        assert body["status"] == "ok" and body["store"]["ok"] is True
        assert body["store"]["error"] is None
    else:
        assert r.status_code == 503, body
        assert body["status"] == "degraded" and body["store"]["ok"] is False
        assert store_error in body["store"]["error"], body
    assert body["version"] and body["jobs_backend"] == "local"
    return body


def open_with(store: Store, monkeypatch, *pragmas: str) -> None:
    """Every new connection of ``store`` runs ``pragmas`` first (a read-only file, a full
    disk: what chmod cannot show when the tests run as root)."""
    real = store._open

    def opener(**kw) -> sqlite3.Connection:
        conn = real(**kw)
        for pragma in pragmas:
            n = conn.execute("PRAGMA page_count").fetchone()[0]
            conn.execute(pragma.format(pages=n))
        return conn

    monkeypatch.setattr(store, "_open", opener)


# ---- /health ------------------------------------------------------------------------------
def test_health_reports_the_store_and_the_jobs(client):
    body = assert_health(client, None)
    store = store_of(client)
    files = [store.path, Path(f"{store.path}-wal"), Path(f"{store.path}-shm")]
    assert body["store"]["bytes"] == sum(f.stat().st_size for f in files if f.exists()) > 0
    assert 0 <= body["store"]["free_bytes"] < body["store"]["bytes"]
    assert body["store"]["job_counts"] == {"queued": 0, "running": 0, "succeeded": 0,
                                           "failed": 0, "cancelled": 0}
    submit(client)
    assert client.get("/health").json()["store"]["job_counts"]["queued"] == 1
    # Built but not served: the job supervisor has not been started, which is no fault.
    assert body["jobs"] == {"ok": True, "running": False, "error": None, "workers": None}


def test_health_503_is_documented_with_the_health_body(client):
    doc = client.get("/openapi.json").json()
    answers = doc["paths"]["/health"]["get"]["responses"]
    for code in ("200", "503"):
        ref = answers[code]["content"]["application/json"]["schema"]["$ref"]
        assert ref.endswith("/Health"), (code, ref)
    health = doc["components"]["schemas"]["Health"]
    assert {"status", "version", "jobs_backend", "store", "jobs"} <= set(health["required"])
    assert set(health["properties"]["status"]["enum"]) == {"ok", "degraded"}


def test_health_check_is_reused_for_a_second(tmp_path, monkeypatch):
    client = TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path)))
    store = store_of(client)
    calls = []
    real = store._check_health
    monkeypatch.setattr(store, "_check_health", lambda: calls.append(1) or real())
    for _ in range(5):
        assert client.get("/health").status_code == 200
    assert len(calls) == 1
    # A store call that fails drops the kept result: /health looks again at once.
    (tmp_path / STORE_FILENAME).unlink()
    assert_store_503(client.get("/jobs"), "missing")
    assert client.get("/health").status_code == 503
    assert len(calls) == 2


def test_health_answers_when_the_store_check_hangs(client, monkeypatch):
    monkeypatch.setattr(health_route, "STORE_CHECK_WAIT_S", 0.2)
    release = threading.Event()
    monkeypatch.setattr(store_of(client), "health", lambda *a: release.wait(5))
    start = time.monotonic()
    try:
        body = assert_health(client, "did not answer within 0.2 s")
    finally:
        release.set()
    assert time.monotonic() - start < 2
    assert body["jobs"]["ok"] is True


@pytest.mark.parametrize("backend, words", [
    (SimpleNamespace(name="local", alive=lambda: False, failing=None),
     "local job supervisor has stopped"),
    (SimpleNamespace(name="dask", alive=lambda: True, failing=None,
                     unavailable=lambda: "the Dask scheduler at tcp://h:1 is unreachable"),
     "Dask scheduler at tcp://h:1 is unreachable"),
    (SimpleNamespace(name="local", alive=lambda: True, failing="StoreError: x",
                     unavailable=lambda: None, parallelism=lambda: 2),
     "failing"),
])
def test_health_names_a_job_backend_that_does_not_work(client, backend, words):
    client.app.state.jobs.backend = backend
    r = client.get("/health")
    assert r.status_code == 503
    body = r.json()
    assert body["status"] == "degraded" and body["store"]["ok"] is True
    assert body["jobs"]["ok"] is False and words in body["jobs"]["error"]
    client.app.state.jobs.backend = SimpleNamespace(
        name="dask", alive=lambda: True, failing=None, unavailable=lambda: None,
        parallelism=lambda: 4)
    assert client.get("/health").json()["jobs"] == {"ok": True, "running": True, "error": None,
                                                    "workers": 4}


# ---- each failure: 503s, then the repaired store is picked up -----------------------------
def test_deleted_store_file_is_reported_not_recreated_and_a_restore_is_picked_up(client,
                                                                                tmp_path):
    job_id = submit(client)
    path = tmp_path / STORE_FILENAME
    backup = tmp_path / "backup.sqlite3"
    shutil.copy(path, backup)
    path.unlink()
    assert_health(client, "missing")
    assert_store_503(client.get(f"/jobs/{job_id}"), "missing")
    assert_store_503(client.get("/jobs"), "missing")
    assert_store_503(client.post("/jobs", json={"kind": "echo", "params": {}}), "missing")
    assert_store_503(client.post("/robots", json=ARM), "missing")
    assert not path.exists()  # never silently replaced by an empty store
    shutil.copy(backup, path)
    assert client.get(f"/jobs/{job_id}").json()["status"] == "queued"
    assert_health(client, None)
    assert client.post("/robots", json=ARM).status_code == 201


@pytest.mark.parametrize("damage, words", [
    ("overwrite", "file is not a database"),
    ("pages", "malformed"),
])
def test_corrupt_store_file_answers_503_until_repaired(client, tmp_path, damage, words):
    job_id = submit(client)
    assert client.post("/robots", json=ARM).status_code == 201
    path = tmp_path / STORE_FILENAME
    good = path.read_bytes()
    assert client.post("/robots", json={**ARM, "id": "added_later"}).status_code == 201
    if damage == "overwrite":
        path.write_bytes(b"\x07 not sqlite \x00" * 4096)
    else:  # keep the header and the schema page, scribble over every table's pages
        page = int.from_bytes(good[16:18], "big")
        path.write_bytes(good[:page] + b"\xa5" * (len(good) - page))
    assert_health(client, words)
    assert_store_503(client.get(f"/jobs/{job_id}"), words)
    assert_store_503(client.delete("/robots/two_link"), words)
    assert_store_503(client.post("/jobs", json={"kind": "echo", "params": {}}), words)
    path.write_bytes(good)  # repaired in place, from a copy that predates one robot
    assert client.get(f"/jobs/{job_id}").status_code == 200
    assert_health(client, None)
    assert client.get("/robots/added_later").status_code == 404
    assert client.delete("/robots/two_link").status_code == 204


def test_read_only_store_serves_reads_and_answers_503_to_writes(client, monkeypatch):
    job_id = submit(client)
    with monkeypatch.context() as m:
        open_with(store_of(client), m, "PRAGMA query_only = ON")
        assert_store_503(client.post("/jobs", json={"kind": "echo", "params": {}}),
                         "readonly database")
        assert_store_503(client.post("/robots", json=ARM), "readonly database")
        assert client.get(f"/jobs/{job_id}").status_code == 200  # reads still work
        assert_health(client, "readonly database")
        assert_health(client, "readonly database")  # a read does not clear a failed write
    submit(client)  # writable again: the first write that works clears it
    assert_health(client, None)


def test_full_disk_answers_503_and_recovers(client, monkeypatch):
    big = "x" * 50_000  # needs new pages
    with monkeypatch.context() as m:
        open_with(store_of(client), m, "PRAGMA max_page_count = {pages}")
        r = client.post("/jobs", json={"kind": "echo", "params": {"value": big}})
        assert_store_503(r, "database or disk is full")
        assert_health(client, "database or disk is full")
        assert client.get("/jobs").json() == []  # nothing half written
    submit(client, big)
    assert_health(client, None)


def test_health_sees_a_full_file_system_and_a_read_only_directory(client, monkeypatch):
    import app.store as store_module

    with monkeypatch.context() as m:
        m.setattr(store_module.os, "statvfs",
                  lambda p: SimpleNamespace(f_bavail=10, f_frsize=4096))
        assert_health(client, "no space left")
    real_access = os.access
    with monkeypatch.context() as m:
        m.setattr(store_module.os, "access",
                  lambda p, mode: Path(p).is_file() and real_access(p, mode))
        assert_health(client, "data directory is read-only")
    assert_health(client, None)


def test_a_directory_in_place_of_the_file(client, tmp_path):
    path = tmp_path / STORE_FILENAME
    path.unlink()
    path.mkdir()
    assert_store_503(client.get("/jobs"), "not a regular file")
    assert_health(client, "not a regular file")


def test_an_emptied_or_older_store_gets_its_tables_back(client, tmp_path):
    path = tmp_path / STORE_FILENAME
    path.unlink()
    path.touch()  # an operator starting over with an empty file
    assert client.get("/jobs").json() == []
    submit(client)
    # A backup from before the jobs table existed: migrated when it is picked up.
    old = tmp_path / "old.sqlite3"
    with sqlite3.connect(old) as conn:
        conn.execute("CREATE TABLE robots (id TEXT PRIMARY KEY, model_json TEXT NOT NULL, "
                     "created TEXT NOT NULL)")
        conn.execute("PRAGMA user_version = 1")
    conn.close()
    os.replace(old, path)
    assert client.get("/jobs").json() == []
    submit(client)
    assert_health(client, None)


def test_a_restored_backup_brings_its_robots(client, tmp_path):
    path = tmp_path / STORE_FILENAME
    assert client.post("/robots", json=ARM).status_code == 201
    backup = tmp_path / "backup.sqlite3"
    shutil.copy(path, backup)
    later = {**ARM, "id": "added_later"}
    assert client.post("/robots", json=later).status_code == 201
    os.replace(backup, path)
    assert_health(client, None)  # the store notices the other file
    assert client.get("/robots/added_later").status_code == 404
    assert client.get("/robots/two_link").status_code == 200


# ---- the job supervisor -------------------------------------------------------------------
@pytest.mark.slow
def test_job_loop_backs_off_logs_once_and_recovers(tmp_path, caplog, monkeypatch):
    monkeypatch.setattr(health_route, "HEALTH_TTL_S", 0.0)
    settings = Settings(no_viewer=True, data_dir=tmp_path, workers=1)
    with TestClient(create_app(settings)) as client:
        store = store_of(client)
        path = tmp_path / STORE_FILENAME
        backup = tmp_path / "backup.sqlite3"
        shutil.copy(path, backup)
        claims = []
        real_claim = store.claim_next_job
        monkeypatch.setattr(store, "claim_next_job", lambda: claims.append(1) or real_claim())
        caplog.set_level(logging.INFO)
        path.unlink()
        time.sleep(1.6)
        # Passes at about 0, 0.1, 0.3, 0.7 and 1.5 s instead of every 0.1 s.
        assert 2 <= len(claims) <= 8, len(claims)
        # One traceback. A pass caught mid-way by the unlink may first see SQLite's own
        # error for a moved file: at most one more line for that other message.
        loop_logs = [r for r in caplog.records if r.name == "app.jobs.backend"]
        assert 1 <= len(loop_logs) <= 2, [r.getMessage() for r in loop_logs]
        assert loop_logs[0].exc_info is not None
        assert all(r.exc_info is None and "still failing" in r.getMessage()
                   for r in loop_logs[1:])
        assert "missing" in f"{loop_logs[0].exc_info[1]} {loop_logs[-1].getMessage()}"
        store_logs = [r.getMessage() for r in caplog.records if r.name == "app.store"]
        assert 1 <= len(store_logs) <= 2 and "missing" in store_logs[-1], store_logs
        body = assert_health(client, "missing")
        assert body["jobs"]["running"] is True and body["jobs"]["ok"] is False
        caplog.clear()
        shutil.copy(backup, path)
        job_id = submit(client, "after repair")  # also ends the back-off wait
        deadline = time.monotonic() + 20
        while (job := client.get(f"/jobs/{job_id}").json())["status"] != "succeeded":
            assert job["status"] in ("queued", "running"), job
            assert time.monotonic() < deadline, job
            time.sleep(0.05)
        assert client.get(f"/jobs/{job_id}/result").json() == {"value": "after repair"}
        recovered = [r.getMessage() for r in caplog.records if r.name == "app.jobs.backend"]
        assert len(recovered) == 1 and "recovered" in recovered[0]
        assert assert_health(client, None)["jobs"] == {"ok": True, "running": True,
                                                       "error": None, "workers": 1}


class _Flaky(SupervisedBackend):
    """Raises ``errors`` in turn (None = a pass that works), then stops itself."""

    name = "flaky"

    def __init__(self, store, errors) -> None:
        super().__init__(store, 1)
        self.errors = list(errors)
        self.waits: list[float] = []
        self.failing_seen: list[str | None] = []
        wake = self._wake
        self._wake = SimpleNamespace(wait=self.waits.append, clear=wake.clear, set=wake.set)

    def _pass(self) -> None:
        self.failing_seen.append(self.failing)
        if not self.errors:
            self._stop.set()
            return
        error = self.errors.pop(0)
        if error is not None:
            raise error


def test_loop_doubles_its_wait_logs_each_message_once_and_the_recovery(monkeypatch, caplog):
    monkeypatch.setattr(backend_module, "RETRY_S", 0.5)
    monkeypatch.setattr(backend_module, "RETRY_MAX_S", 3.0)
    caplog.set_level(logging.INFO, logger="app.jobs.backend")
    a, b = OSError("disk gone"), StoreError(Path("s"), "file is not a database")
    backend = _Flaky(None, [a, a, b, a, b, a, None, None, a, None])
    backend._loop()
    assert backend.waits == [0.5, 1.0, 2.0, 3.0, 3.0, 3.0, 0.5]
    messages = [(r.levelname, r.getMessage(), r.exc_info is not None) for r in caplog.records]
    assert messages[0][0] == "ERROR" and messages[0][2]  # the traceback, once
    assert messages[1] == ("WARNING", "flaky job supervisor pass still failing: StoreError: "
                           "cannot use the store at s: file is not a database", False)
    assert "recovered after" in messages[2][1]
    assert messages[3][0] == "ERROR" and "recovered after" in messages[4][1]
    assert len(messages) == 5
    assert backend.failing_seen[1] == "OSError: disk gone" and backend.failing is None


# ---- start-up -----------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize("make, words", [
    (lambda p: p.write_bytes(b"this is no database" * 500), "file is not a database"),
    (lambda p: p.mkdir(), "is a directory"),
])
@pytest.mark.cluster
def test_start_on_an_unusable_store_exits_with_one_line(tmp_path, make, words):
    make(tmp_path / STORE_FILENAME)
    proc = subprocess.run(
        [sys.executable, "-m", "kinoplan", "--no-viewer", "--port", str(_free_port()),
         "--data-dir", str(tmp_path)],
        cwd=REPO, capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode != 0
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"kinoplan: cannot use the store at {tmp_path}")
    assert words in lines[0] and "Traceback" not in proc.stderr


def test_start_on_a_read_only_store_or_data_dir_exits_with_one_line(tmp_path, monkeypatch,
                                                                    capsys):
    Store.in_data_dir(tmp_path)
    real_open = Store._open

    def read_only(self, **kw):
        conn = real_open(self, **kw)
        conn.execute("PRAGMA query_only = ON")
        return conn

    with monkeypatch.context() as m:
        m.setattr(Store, "_open", read_only)
        assert main(["--no-viewer", "--data-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"kinoplan: cannot use the store at {tmp_path / STORE_FILENAME}: "
                   "attempt to write a readonly database"]
    not_a_dir = tmp_path / "file"
    not_a_dir.write_text("")
    assert main(["--no-viewer", "--data-dir", str(not_a_dir)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{not_a_dir} is not a directory" in err[0]


def test_store_construction_names_what_is_wrong(tmp_path, monkeypatch):
    import app.store as store_module

    Store.in_data_dir(tmp_path)
    monkeypatch.setattr(store_module.os, "access", lambda p, mode: False)
    with pytest.raises(StoreError, match="the store file is read-only") as info:
        Store.in_data_dir(tmp_path)
    assert info.value.reason == "the store file is read-only"
