"""Every POST with a JSON body publishes request examples in /openapi.json (what /docs shows
under "Example Value"), and each example, sent as it is to a fresh service with the built-in
robots, answers 2xx. Under ``/robots/{robot_id}/...`` the body schema's ``x-example-robot``
names the built-in robot the examples are written for."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from fastapi.testclient import TestClient

from app.config import Settings
from app.main import create_app


@pytest.fixture(scope="module")
def shown(tmp_path_factory) -> Iterator[TestClient]:
    """A fresh service with the 3D viewer (on a free port), so ``POST /viewer/show`` works;
    not entered, so submitted jobs stay queued."""
    from web.viewer import Viewer

    api = create_app(Settings(no_viewer=True, data_dir=tmp_path_factory.mktemp("examples"),
                              workers=1, prebuild_collision=False))
    api.state.viewer = Viewer.start("127.0.0.1", 0, api.state, environment_map=False)
    yield TestClient(api)
    api.state.viewer.stop()
    api.state.compute.shutdown()


def _resolve(schema: dict, document: dict) -> dict:
    while "$ref" in schema:
        schema = document["components"]["schemas"][schema["$ref"].split("/")[-1]]
    return schema


def json_bodies(document: dict) -> list[tuple[str, dict, dict]]:
    """(path, media type object, resolved schema) of every POST taking a JSON body."""
    out = []
    for path, operations in document["paths"].items():
        body = operations.get("post", {}).get("requestBody")
        if body and "application/json" in body["content"]:
            media = body["content"]["application/json"]
            out.append((path, media, _resolve(media.get("schema", {}), document)))
    return out


def examples_of(media: dict, schema: dict) -> list:
    """The request examples published for a body: the media type's and the schema's."""
    found = [e["value"] for e in media.get("examples", {}).values() if "value" in e]
    found += [media["example"]] if "example" in media else []
    found += list(schema.get("examples", []))
    found += [schema["example"]] if "example" in schema else []
    return found


def test_every_json_post_has_an_example(shown):
    document = shown.get("/openapi.json").json()
    bodies = json_bodies(document)
    assert len(bodies) >= 17   # fk ... viewer/show: a route that lost its body would show
    missing = [path for path, media, schema in bodies if not examples_of(media, schema)]
    assert not missing, missing
    for path, _, schema in bodies:
        if "{robot_id}" in path:
            assert schema.get("x-example-robot"), path


@pytest.mark.slow
def test_every_example_answers_2xx_on_a_fresh_service(shown, motion_kernels):
    document = shown.get("/openapi.json").json()
    builtins = {r["id"] for r in shown.get("/robots").json()}
    sent = 0
    for path, media, schema in json_bodies(document):
        url = path.replace("{robot_id}", str(schema.get("x-example-robot")))
        assert "{" not in url, path
        if "{robot_id}" in path:
            assert schema["x-example-robot"] in builtins, path
        for example in examples_of(media, schema):
            r = shown.post(url, json=example)
            assert 200 <= r.status_code < 300, (url, example, r.status_code, r.text[:400])
            sent += 1
    assert sent >= 20


def test_a_model_with_examples_still_forbids_unknown_fields(shown):
    """The examples' model_config is merged with the request bodies' strictness."""
    r = shown.post("/robots/glt_palletizer/jacobian",
                   json={"q": [0.0] * 6, "typo": 1})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"] == ["body", "typo"]
