"""Jobs split into steps: spread over the local backend's processes, results as inline."""

from __future__ import annotations

import os
import time

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs.graph import Ref, Step, Tracker, check, run_inline
from app.jobs.kinds import KINDS
from app.main import create_app

from . import graph_kinds
from .conftest import wait_for


@pytest.fixture
def fan_client(tmp_path, monkeypatch):
    monkeypatch.setitem(KINDS, graph_kinds.NAME, graph_kinds.KIND)
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=2))) as c:
        yield c


def submit(client, **params):
    r = client.post("/jobs", json={"kind": graph_kinds.NAME, "params": params})
    assert r.status_code == 202, r.text
    return r.json()["id"]


def overlapping(parts: list[dict]) -> int:
    """The most parts running at one instant."""
    events = sorted([(p["start"], 1) for p in parts] + [(p["end"], -1) for p in parts],
                    key=lambda e: (e[0], e[1]))
    most = now = 0
    for _, d in events:
        now += d
        most = max(most, now)
    return most


@pytest.mark.slow
def test_the_parts_of_one_job_run_at_once_in_separate_processes(fan_client):
    job_id = submit(fan_client, parts=4, part_s=1.0)
    seen = []
    while (job := fan_client.get(f"/jobs/{job_id}").json())["status"] in ("queued", "running"):
        seen.append((job["progress"], job["message"]))
        time.sleep(0.05)
    assert job["status"] == "succeeded", job
    result = fan_client.get(f"/jobs/{job_id}/result").json()
    assert result["total"] == 1 + 4 + 9 + 16
    assert [p["index"] for p in result["parts"]] == [0, 1, 2, 3]
    assert len({p["pid"] for p in result["parts"]}) == 4  # a fresh process per step
    assert overlapping(result["parts"]) == 2  # two slots, both used, never more
    assert job["attempts"] == 1
    fractions = [p for p, _ in seen if 0 < p < 1]
    assert fractions and fractions == sorted(fractions)
    assert any(m.startswith("part ") for _, m in seen)


@pytest.mark.slow
def test_the_same_result_inline_and_on_the_backend(fan_client):
    params = graph_kinds.FanParams(parts=3, part_s=0.0)
    inline = run_inline(graph_kinds.graph(params), params, lambda f, m: None)
    job_id = submit(fan_client, parts=3, part_s=0.0)
    assert wait_for(fan_client, job_id)["status"] == "succeeded"
    result = fan_client.get(f"/jobs/{job_id}/result").json()
    assert result["total"] == inline.total
    assert [p["value"] for p in result["parts"]] == [p.value for p in inline.parts]


@pytest.mark.slow
def test_a_failing_part_fails_the_job_and_stops_the_others(fan_client):
    # Part 1 fails after 3 s; part 0 would go on for 27 s more.
    job_id = submit(fan_client, parts=2, part_s=30.0, fail=1)
    job = wait_for(fan_client, job_id, timeout=30)
    assert job["status"] == "failed"
    assert job["error"] == "RuntimeError: part 1 was asked to fail"
    # Part 0 was stopped with its job: the next job gets both slots long before part 0
    # would have ended (the margin is for a loaded machine).
    after = submit(fan_client, parts=2, part_s=0.0)
    assert wait_for(fan_client, after, timeout=15)["status"] == "succeeded"


def test_cancel_kills_every_process_of_the_job(fan_client):
    job_id = submit(fan_client, parts=2, part_s=30.0, busy=True)
    wait_for(fan_client, job_id, statuses=("running",))
    backend = fan_client.app.state.jobs.backend
    deadline = time.monotonic() + 10
    while len(backend._procs()) < 2:
        assert time.monotonic() < deadline
        time.sleep(0.05)
    pids = [run.process.pid for run in backend._procs()]
    assert fan_client.delete(f"/jobs/{job_id}").status_code == 200
    t0 = time.monotonic()
    assert wait_for(fan_client, job_id)["status"] == "cancelled"
    while any(_alive(pid) for pid in pids):
        assert time.monotonic() - t0 < 2.0, "a step's process outlived its job's cancel by 2 s"
        time.sleep(0.02)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie not reaped yet has stopped too
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[1][0] != "Z"
    except OSError:
        return False


@pytest.mark.slow
def test_an_older_jobs_ready_steps_go_first(fan_client):
    first = submit(fan_client, parts=4, part_s=0.6)
    second = submit(fan_client, parts=1, part_s=0.0)
    assert wait_for(fan_client, second)["status"] == "succeeded"
    assert wait_for(fan_client, first)["status"] == "succeeded"
    a = fan_client.get(f"/jobs/{first}/result").json()["parts"]
    b = fan_client.get(f"/jobs/{second}/result").json()["parts"][0]
    # The second job's part starts once the first job's four parts have all started.
    assert b["start"] >= max(p["start"] for p in a)


# ---- the graph itself -----------------------------------------------------------------------
def _double(params, x, progress):
    return 2 * x


def _add(params, xs, progress):
    return sum(xs)


def test_run_inline_resolves_refs_in_lists_and_reports_weighted_progress():
    steps = [Step(_double, (1,), weight=1.0), Step(_double, (2,), weight=3.0),
             Step(_add, ([Ref(0), Ref(1), 10],))]
    seen = []
    assert run_inline(steps, None, lambda f, m: seen.append(f)) == 2 + 4 + 10
    tracker = Tracker(steps)
    assert tracker.update(1, 0.5) == pytest.approx(1.5 / 5)


def test_a_graph_must_refer_backwards():
    with pytest.raises(ValueError, match="step 0 refers"):
        check([Step(_double, (Ref(0),))])
    with pytest.raises(ValueError, match="at least one step"):
        check([])
    with pytest.raises(ValueError, match="weight"):
        Step(_double, weight=0)
