"""Deeply nested JSON bodies: every route that takes a body answers 4xx, never 500.

orjson refuses nesting deeper than 1,024 levels; the standard library, which read what
orjson refused, recursed until Python's stack limit and the route answered 500."""

from __future__ import annotations

import json
import re

import pytest

from app.responses import MAX_JSON_DEPTH, loads_json

#: Path parameters filled with values that exist in a fresh service (or not: a 404 is 4xx).
PATH_VALUES = {"robot_id": "glt_palletizer", "rig_id": "tunnel_jumbo", "job_id": "nojob",
               "scene_id": "noscene", "mesh_id": "nomesh"}

DEEP_ARRAYS = b"[" * 2000 + b"]" * 2000
DEEP_OBJECTS = b'{"a":' * 10_000 + b"1" + b"}" * 10_000
DEEP_IN_A_FIELD = b'{"q": ' + b"[" * 2000 + b"]" * 2000 + b"}"
# Deep and with a NaN token: orjson refuses the token, the standard library the depth.
DEEP_WITH_NAN = b"[" * 1500 + b"NaN" + b"]" * 1500


def _body_routes(client) -> list[tuple[str, str, bool]]:
    """(method, path, whether its body is JSON) of every route that takes a body."""
    doc = client.get("/openapi.json").json()
    out = []
    for path, ops in doc["paths"].items():
        for method in ("post", "put", "patch"):
            if method in ops:
                filled = re.sub(r"\{(\w+)\}", lambda m: PATH_VALUES.get(m.group(1), "x"), path)
                content = (ops[method].get("requestBody") or {}).get("content", {})
                out.append((method, filled, not content or "application/json" in content))
    return out


def test_the_reader_names_the_depth():
    assert loads_json(b"[" * MAX_JSON_DEPTH + b"]" * MAX_JSON_DEPTH) is not None
    for body in (DEEP_ARRAYS, DEEP_OBJECTS, DEEP_WITH_NAN, DEEP_WITH_NAN.decode()):
        with pytest.raises(json.JSONDecodeError, match="nested deeper than 1024"):
            loads_json(body)


def test_every_route_with_a_body_refuses_deep_nesting(client):
    """A JSON route answers 422 saying why (one reader for all: a route on
    Starlette's own reader answered 400 "There was an error parsing the body"); a route
    that takes files refuses the JSON content type."""
    routes = _body_routes(client)
    assert sum(json_body for *_, json_body in routes) >= 15
    bad = []
    for method, path, json_body in routes:
        for body in (DEEP_ARRAYS, DEEP_OBJECTS, DEEP_IN_A_FIELD, DEEP_WITH_NAN):
            r = client.request(method.upper(), path, content=body,
                               headers={"content-type": "application/json"})
            if not json_body:
                if not 400 <= r.status_code < 500:
                    bad.append((method, path, body[:12], r.status_code))
                continue
            detail = r.json()["detail"] if r.status_code == 422 else [{}]
            if r.status_code != 422 or "nested deeper than 1024" not in detail[0].get("msg", ""):
                bad.append((method, path, body[:12], r.status_code, detail[0]))
    assert not bad


def test_a_deep_fk_body_is_a_422_naming_the_body(client):
    r = client.post("/robots/glt_palletizer/fk", content=DEEP_IN_A_FIELD,
                    headers={"content-type": "application/json"})
    assert r.status_code == 422
    detail = r.json()["detail"][0]
    assert detail["loc"][0] == "body" and detail["type"] == "json_invalid"
    assert "nested deeper than 1024" in detail["msg"]


def test_a_deep_fixed_joints_form_field_is_a_422(client):
    r = client.post("/robots/import", files={"file": ("a.urdf", b"<robot name='a'/>")},
                    data={"fixed_joints": "[" * 2000 + "]" * 2000})
    assert r.status_code == 422
