"""Fixtures of the API tests: a fresh application per test, no viewer, data in a temp dir."""

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
