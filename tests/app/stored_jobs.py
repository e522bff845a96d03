"""Jobs written into a service's store as a worker leaves them, for the tests of what the
service derives from finished jobs (trajectory files, replays)."""

from __future__ import annotations

import json

from fastapi.testclient import TestClient

from app.jobs.catalog import KINDS


def store_job(client: TestClient, job_id: str, kind: str, params: dict, result: dict | None,
              status: str = "succeeded", error: str | None = None) -> None:
    """A job of ``kind`` as the service keeps it once ended (``result`` checked against the
    kind's result model first), or queued when ``status`` is 'queued'."""
    store = client.app.state.store
    store.add_job(job_id, kind, params, {})
    if status == "queued":
        return
    text = None
    if result is not None:
        KINDS[kind].load_result(result)
        text = json.dumps(result)
    store.finish_job(job_id, status, result_json=text, error=error)
