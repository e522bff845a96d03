"""Shared fixtures: the papers' printed numbers."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="session")
def paper_tables() -> dict:
    """Every number the seed papers print that a test can reproduce (angles in degrees)."""
    return json.loads((DATA / "paper_tables.json").read_text())
