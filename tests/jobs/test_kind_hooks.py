"""The job manager calls a kind's hooks (``JobKind.prepare``, ``check``, ``needs_geometry``,
``keep_latest``), never a kind by its name: a toy kind declared through the public kind API
exercises each hook, and no kind's name is written in the manager."""

from __future__ import annotations

import ast
import sqlite3
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from app.jobs import manager as manager_module
from app.jobs.catalog import KINDS
from app.jobs.kinds import JobKind, register
from app.jobs.manager import JobManager, JobParamsError, served_kinds
from app.registry import RobotRegistry
from app.store import STORE_FILENAME, Store

from . import toy_kind

MANAGER_SOURCE = Path(manager_module.__file__).read_text()


def string_literals(source: str) -> set[str]:
    """Every string constant of a module's source (docstrings and f-string parts included)."""
    return {node.value for node in ast.walk(ast.parse(source))
            if isinstance(node, ast.Constant) and isinstance(node.value, str)}


def test_the_literal_scan_finds_a_kind_name_where_there_is_one():
    # The way the manager used to pick a kind's special case: the scan below must see it.
    found = string_literals('def submit(kind):\n    if kind in ("path", "path_compare"):\n'
                            '        pass\n    x = f"{kind} motion"\n')
    assert {"path", "path_compare"} <= found and "motion" not in found


def test_no_kind_name_is_written_in_the_manager():
    assert len(KINDS) >= 10  # the catalog's kinds are loaded
    assert not string_literals(MANAGER_SOURCE) & set(KINDS)


# ---- a toy kind's hooks through the manager ----------------------------------------------
class Scenes:
    """Stored scenes as the manager's ``scenes`` shows them to a ``prepare`` hook."""

    def __init__(self, **objects: int) -> None:
        self._scenes = {k: {"id": k, "objects": [{}] * n} for k, n in objects.items()}

    def describe(self, scene_id: str) -> dict:
        return self._scenes[scene_id]


class Robots(RobotRegistry):
    """The built-in robots, each with the geometry files an imported robot would carry."""

    def robot_files(self, robot_id: str) -> dict[str, str] | None:
        self.get(robot_id)
        return {"description": f"geometry of {robot_id}"}


@pytest.fixture
def toy():
    kind = register(toy_kind.KIND)
    yield kind
    del KINDS[kind.name]


@pytest.fixture
def manager(tmp_path):
    store = Store(tmp_path / STORE_FILENAME)
    jobs = JobManager(store, Robots(store), "local", 1, 10, retention_days=7)
    jobs.scenes = Scenes(cell=3)
    return jobs  # not started: a submitted job stays queued


def test_prepare_rewrites_the_submitted_params_before_validation(toy, manager):
    job = manager.submit(toy.name, {"robot": "glt_palletizer", "count": 10, "scene": "cell"})
    assert job.params["scene"] is None and job.params["scene_objects"] == 3
    with pytest.raises(JobParamsError) as err:
        manager.submit(toy.name, {"robot": "glt_palletizer", "scene": "nowhere"})
    assert (err.value.status, err.value.loc) == (404, ["params", "scene"])
    assert err.value.message == "unknown scene 'nowhere'"


def test_check_sees_the_validated_params_and_the_robot(toy, manager):
    manager.submit(toy.name, {"robot": "glt_palletizer", "count": 6000})  # 6 joints: 6000 at most
    with pytest.raises(JobParamsError) as err:
        manager.submit(toy.name, {"robot": "glt_palletizer", "count": 6001})
    assert (err.value.status, err.value.loc) == (422, ["params", "count"])
    assert err.value.message == "at most 6000 configurations for a robot of 6 joints"
    # Invalid params never reach the hook: pydantic's error stands.
    with pytest.raises(JobParamsError) as err:
        manager.submit(toy.name, {"robot": "glt_palletizer", "count": 0})
    assert err.value.loc == ["params", "count"] and "greater than or equal" in err.value.message
    # An unknown robot is the manager's 404, after the hook let it pass.
    with pytest.raises(JobParamsError) as err:
        manager.submit(toy.name, {"robot": "no_such_arm"})
    assert (err.value.status, err.value.loc) == (404, ["params", "robot"])


def test_needs_geometry_puts_the_robot_files_in_the_payload(toy, manager, monkeypatch):
    job = manager.submit(toy.name, {"robot": "glt_palletizer"})
    assert manager.store.job_payload(job.id)["robot_files"] == {
        "description": "geometry of glt_palletizer"}
    plain = JobKind("toy_plain", toy_kind.ToyParams, toy_kind.ToyResult, toy_kind.run_toy,
                    "without the hooks", needs_robot=True)
    monkeypatch.setitem(KINDS, plain.name, plain)
    job = manager.submit(plain.name, {"robot": "glt_palletizer", "scene": "cell"})
    payload = manager.store.job_payload(job.id)
    assert "robot_files" not in payload and payload["robot_model"]["id"] == "glt_palletizer"
    assert job.params["scene"] == "cell"  # no prepare hook: as given


def _ended(store: Store, job_id: str, kind: str, robot: str, days_ago: float) -> None:
    store.add_job(job_id, kind, {"robot": robot}, {"params": {}})
    store.claim_next_job()
    store.finish_job(job_id, "succeeded", result_json="{}")
    with sqlite3.connect(store.path) as conn:
        when = datetime.now(UTC) - timedelta(days=days_ago)
        conn.execute("UPDATE jobs SET finished = ? WHERE id = ?",
                     (when.isoformat(timespec="microseconds"), job_id))


def test_keep_latest_spares_the_latest_job_per_robot_from_retention(toy, manager):
    assert toy.name in served_kinds() and "echo" not in served_kinds()
    store = manager.store
    for k, robot in enumerate(["glt_palletizer", "glt_palletizer", "pile_driver"]):
        _ended(store, f"toy-{k}", toy.name, robot, 30 - k)
        _ended(store, f"echo-{k}", "echo", robot, 30 - k)
    assert manager.maintain()[0] == 4
    assert {j.id for j in store.list_jobs()} == {"toy-1", "toy-2"}
