"""The recipe "Adding a job kind" (docs/extending.md), followed step by step with the toy
kind of ``toy_kind``: declared (params, result, run, hooks), registered, listed by
``GET /jobs/kinds``, submitted through ``POST /jobs`` on a served app, run to completion by
the local backend's worker processes, and its result fetched and read back with the kind's
result model."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.jobs.catalog import KINDS
from app.jobs.kinds import register
from app.main import create_app
from kinematics.fk import fk
from kinematics.library import builtin_model

from . import toy_kind
from .conftest import wait_for


def _at(x: float, y: float, z: float) -> list[list[float]]:
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


@pytest.fixture
def toy():
    """Step 5 of the recipe (the catalog imports the kind's module, which registers it),
    done here for the length of a test."""
    kind = register(toy_kind.KIND)
    yield kind
    del KINDS[kind.name]


@pytest.fixture
def client(tmp_path, toy):
    with TestClient(create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1,
                                        prebuild_collision=False))) as c:
        yield c


def test_a_registered_name_is_refused_a_second_time(toy):
    with pytest.raises(ValueError, match="already registered"):
        register(toy_kind.KIND)


def test_the_kind_is_listed_with_its_schemas(client, toy):
    listed = {k["kind"]: k for k in client.get("/jobs/kinds").json()}
    entry = listed[toy.name]
    assert entry["params_schema"]["properties"]["count"]["maximum"] == 100_000
    assert set(entry["result_schema"]["properties"]) == set(toy_kind.ToyResult.model_fields)
    assert entry["plot"] is False


def test_submitted_run_and_fetched_through_the_service(client, toy):
    scene = {"id": "cell", "objects": [
        {"type": "sphere", "id": "ball", "radius": 100, "pose": _at(2000, 0, 500)},
        {"type": "box", "id": "crate", "size": [200, 200, 200], "pose": _at(0, 2000, 500)}]}
    assert client.post("/scenes", json=scene).status_code == 201
    r = client.post("/jobs", json={"kind": toy.name, "params": {
        "robot": "glt_palletizer", "count": 500, "seed": 7, "scene": "cell"}})
    assert r.status_code == 202, r.text
    job = r.json()
    assert job["kind"] == toy.name and job["params"]["scene_objects"] == 2  # prepare ran
    assert wait_for(client, job["id"])["status"] == "succeeded"
    r = client.get(f"/jobs/{job['id']}/result")
    assert r.status_code == 200
    result = toy.load_result(r.text)  # the kind's own model reads it back
    # The same figures computed here from the same seed, as the kind's docstring says.
    model = builtin_model("glt_palletizer")
    q = np.random.default_rng(7).uniform(model.lower, model.upper, size=(500, model.dof))
    p = fk(model, q)[:, :3, 3]
    radial = np.hypot(p[:, 0], p[:, 1])
    assert result.robot == "glt_palletizer" and result.count == 500
    assert result.scene_objects == 2
    assert result.reach == pytest.approx(radial.max(), rel=1e-12)
    np.testing.assert_allclose(result.farthest, p[np.argmax(radial)], rtol=1e-12)


def test_the_hooks_answer_through_the_service(client, toy):
    r = client.post("/jobs", json={"kind": toy.name, "params": {
        "robot": "glt_palletizer", "scene": "nowhere"}})
    assert r.status_code == 404
    assert r.json()["detail"][0]["loc"] == ["body", "params", "scene"]
    r = client.post("/jobs", json={"kind": toy.name, "params": {
        "robot": "glt_palletizer", "count": 6001}})
    assert r.status_code == 422
    assert r.json()["detail"][0] == {
        "loc": ["body", "params", "count"], "type": "value_error",
        "msg": "at most 6000 configurations for a robot of 6 joints"}
