"""Shared fixtures: the papers' printed numbers, compiled kernels, a fake clock."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"

# The in-process test client calls itself "testserver": let the apps the tests build serve
# that name. The Host allow-list's own defaults are tested with explicit settings
# (tests/app/test_request_guard.py).
os.environ.setdefault("KINOPLAN_ALLOWED_HOSTS", "*")
# Apps built by tests start compute workers only when a test asks for one (each would start
# and warm two processes otherwise); tests/app/test_compute_prestart.py tests the default.
os.environ.setdefault("KINOPLAN_PRESTART_COMPUTE", "0")


@pytest.fixture(scope="session")
def paper_tables() -> dict:
    """Every number the seed papers print that a test can reproduce (angles in degrees)."""
    return json.loads((DATA / "paper_tables.json").read_text())


@pytest.fixture(scope="session")
def motion_kernels() -> None:
    """The motion planner's compiled kernels loaded (compiled, on a machine whose cache is
    cold) before a test gives a plan a short time limit."""
    from planning.motion import warm_up

    warm_up()


class FakeClock:
    """A clock that moves ``step`` s each time it is read."""

    def __init__(self, step: float) -> None:
        self.t = 0.0
        self.step = step

    def __call__(self) -> float:
        self.t += self.step
        return self.t


@pytest.fixture
def fake_clock():
    """``fake_clock(step)``: a clock (a callable) that moves ``step`` s at each reading."""
    return FakeClock
