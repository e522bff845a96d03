"""Fixtures of the API tests: no viewer, data in a temp dir; a fresh application per test
(``client``), or one per module for the tests that only read (``ro_client``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app


@pytest.fixture
def client(tmp_path) -> Iterator[TestClient]:
    """A test client of a new app without the 3D viewer, storing its data under tmp_path
    (imported robots' collision models built at their first query, not at import)."""
    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, prebuild_collision=False))
    yield TestClient(api)
    api.state.compute.shutdown()  # worker processes of large requests, if any started


@pytest.fixture(scope="module")
def ro_client(tmp_path_factory) -> Iterator[TestClient]:
    """``client``'s app, shared by the tests of a module that change nothing in it: they only
    read, or compute answers (FK, IK, trajectories, cylinders...) without storing anything,
    adding a robot or scene, or starting a job. A test that writes takes ``client``."""
    data_dir = tmp_path_factory.mktemp("ro_client")
    api = create_app(Settings(no_viewer=True, data_dir=data_dir, prebuild_collision=False))
    yield TestClient(api)
    api.state.compute.shutdown()
