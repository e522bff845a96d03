"""Shared fixtures: the papers' printed numbers, compiled kernels, a fake clock, and the
OpenAPI document built once per test run."""

from __future__ import annotations

import copy
import json
import os
from collections.abc import Iterator
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


def _openapi_inputs(kwargs: dict) -> tuple:
    """What FastAPI's ``get_openapi`` reads to build an app's document: the app's names and,
    route by route (those it publishes), its path, methods, endpoint, response model and
    dependencies. Every app ``create_app`` builds has the same (its routers are fixed at
    import)."""
    routes = tuple(
        (type(r), getattr(r, "path", None), tuple(sorted(getattr(r, "methods", None) or ())),
         getattr(r, "endpoint", None), getattr(r, "name", None),
         getattr(r, "response_model", None),
         tuple(d.dependency for d in getattr(r, "dependencies", ())))
        for r in kwargs["routes"] if getattr(r, "include_in_schema", True))
    names = tuple(kwargs.get(k) for k in ("title", "version", "description", "summary",
                                          "openapi_version"))
    return names, routes


@pytest.fixture(scope="session", autouse=True)
def openapi_built_once() -> Iterator[None]:
    """Each app's OpenAPI document (0.5-1 s of CPU, built at an app's first request by its
    request guard) is built once per test run for the same routes and then copied: hundreds
    of tests build a fresh app. Each app still adds its own ``x-max-body-bytes`` (from its
    settings) to its copy."""
    import fastapi.applications
    from fastapi.openapi.utils import get_openapi

    built: dict[tuple, dict] = {}

    def get_openapi_once(**kwargs) -> dict:
        key = _openapi_inputs(kwargs)
        if key not in built:
            built[key] = get_openapi(**kwargs)
        return copy.deepcopy(built[key])

    patch = pytest.MonkeyPatch()
    patch.setattr(fastapi.applications, "get_openapi", get_openapi_once)
    yield
    patch.undo()


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
