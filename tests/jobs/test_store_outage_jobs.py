"""A store outage while jobs run loses no job: outcomes and claimed jobs wait for it."""

from __future__ import annotations

import json
import time

from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app
from app.store import StoreError

from .conftest import wait_for


def _outage(store, method: str, monkeypatch):
    """Make ``store.<method>`` fail as a full disk would, until the returned ``repair()``."""
    original = getattr(store, method)
    failed = []

    def broken(*args, **kwargs):
        failed.append(args)
        raise StoreError(store.path, "database or disk is full")

    monkeypatch.setattr(store, method, broken)
    return failed, lambda: monkeypatch.setattr(store, method, original)


def test_an_outcome_reached_during_an_outage_is_saved_after_it(tmp_path, monkeypatch):
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))) as c:
        store = c.app.state.store
        failed, repair = _outage(store, "finish_job", monkeypatch)
        job_id = c.post("/jobs", json={"kind": "sleep",
                                       "params": {"seconds": 0.2, "steps": 2}}).json()["id"]
        deadline = time.monotonic() + 30
        while len(failed) < 2:  # the job ended; saving its result failed, and was retried
            assert time.monotonic() < deadline
            time.sleep(0.05)
        assert c.get(f"/jobs/{job_id}").json()["status"] == "running"
        repair()
        job = wait_for(c, job_id)
        assert job["status"] == "succeeded"
        assert json.loads(c.get(f"/jobs/{job_id}/result").text)["slept"] == 0.2


def test_a_job_claimed_during_an_outage_still_runs(tmp_path, monkeypatch):
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))) as c:
        store = c.app.state.store
        failed, repair = _outage(store, "job_payload", monkeypatch)
        job_id = c.post("/jobs", json={"kind": "sleep", "params": {"seconds": 0}}).json()["id"]
        deadline = time.monotonic() + 30
        while not failed:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        repair()
        assert wait_for(c, job_id)["status"] == "succeeded"
