"""Compute workers started with the service: the first synchronous plans of a fresh service
waited seconds past their time limit while a worker started and loaded its kernels."""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from app.compute import ComputePool
from app.config import Settings
from app.main import create_app


def _processes(pool: ComputePool) -> list:
    executor = pool._executor
    return list((getattr(executor, "_processes", None) or {}).values())


def _loaded() -> tuple[int, bool]:
    """In a worker: its pid, and whether the kernels its requests run (``KERNELS`` of
    ``planning.warm``, the motion planner's included) have loaded."""
    import os

    from app.compute import KERNELS
    from planning import warm
    from planning.motion import warm as motion_warm

    return os.getpid(), motion_warm._done and set(KERNELS) <= set(warm._seconds)


def test_the_service_starts_its_workers_by_default():
    assert Settings.model_fields["prestart_compute"].default is True


@pytest.mark.slow
def test_prestart_starts_every_worker_and_loads_its_kernels():
    pool = ComputePool(2, 8)
    try:
        pool.prestart()
        assert len(_processes(pool)) == 2   # before any request
        # The workers load their kernels (a plan waits for nothing afterwards).
        deadline = time.monotonic() + 300
        loaded: set[int] = set()
        while len(loaded) < 2 and time.monotonic() < deadline:
            pid, done = pool._executor.submit(_loaded).result(timeout=300)
            if done:
                loaded.add(pid)
        assert loaded == {p.pid for p in _processes(pool)}
    finally:
        pool.shutdown()


def test_the_app_starts_its_workers_with_its_lifespan(tmp_path):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, prebuild_collision=False,
                              compute_workers=2, prestart_compute=True))
    with TestClient(api):
        deadline = time.monotonic() + 30
        while len(_processes(api.state.compute)) < 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        assert len(_processes(api.state.compute)) == 2
    assert api.state.compute._executor is None   # stopped with the service


def test_without_prestart_no_worker_runs_until_asked(tmp_path):
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, prebuild_collision=False,
                              prestart_compute=False))
    with TestClient(api):
        assert api.state.compute._executor is None
