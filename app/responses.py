"""Fast JSON in and out of the API, and a compact binary answer for batch endpoints.

* **Answers** are encoded by orjson (``dumps``): numpy arrays are written directly
  (``OPT_SERIALIZE_NUMPY``), no ``tolist`` first, compact, UTF-8. NaN and infinities are
  written as ``null`` (as ``kinematics.numbers.finite_or_none`` does for single numbers):
  non-finite numbers never appear in JSON. ``FastJSONResponse`` renders that way;
  ``legacy`` answers with the standard library instead, as the service did before (the
  figures of ``benchmarks/bench_rest.py`` compare both; set ``KINOPLAN_JSON_ENCODER=stdlib``
  to serve that way, for measuring only).
* **Request bodies** are decoded by orjson too (``FastJSONRoute``, ``read_json``): a body
  orjson refuses (``NaN`` or ``Infinity`` tokens, which the standard library reads) is read
  by the standard library as before, so every validation error keeps its status and its
  field. A route that reads its body itself (``request_body``) validates it with
  ``validate_body``, whose errors are FastAPI's own (``loc`` starting with ``"body"``).
* **Binary answers**: with ``Accept: application/x-npy`` a batch endpoint answers with its
  main array in NumPy's ``.npy`` format (``np.save``; read with ``np.load(io.BytesIO(...))``),
  float64, C order. Which array, and its shape, is each endpoint's own (docs/API.md).
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Callable, Coroutine
from typing import Any

import numpy as np
import orjson
from fastapi import HTTPException
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute
from pydantic import BaseModel, ValidationError
from starlette.requests import Request
from starlette.responses import Response

__all__ = [
    "NPY_MEDIA_TYPE",
    "NPY_RESPONSE",
    "FastJSONRequest",
    "FastJSONResponse",
    "FastJSONRoute",
    "answer",
    "dumps",
    "legacy",
    "loads_json",
    "MAX_JSON_DEPTH",
    "npy_bytes",
    "MISSING",
    "body_schema",
    "read_json",
    "request_body",
    "validate_body",
    "wants_npy",
]

#: Media type of the binary answers (NumPy's ``.npy`` format).
NPY_MEDIA_TYPE = "application/x-npy"
#: ``legacy`` (set from ``KINOPLAN_JSON_ENCODER=stdlib``): answers encoded by the standard
#: library after ``tolist``, as the service did before; for before/after measurements.
legacy = os.environ.get("KINOPLAN_JSON_ENCODER", "").strip().lower() == "stdlib"

_OPTIONS = orjson.OPT_SERIALIZE_NUMPY | orjson.OPT_NON_STR_KEYS


def _default(value: Any) -> Any:
    """What orjson cannot write itself: arrays that are not C-contiguous or not of a plain
    numeric type, numpy scalars of other types."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "fiub" and not value.flags.c_contiguous:
            return np.ascontiguousarray(value)
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot encode {type(value).__name__} as JSON")


def _listed(value: Any) -> Any:
    """Arrays as lists and numpy scalars as Python numbers, for the standard library's
    encoder (what the service did before: ``tolist``, then ``json.dumps``)."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot encode {type(value).__name__} as JSON")


def dumps(content: Any) -> bytes:
    """``content`` (dicts, lists, numbers, strings, numpy arrays and scalars) as compact UTF-8
    JSON; NaN and infinities become ``null``."""
    if legacy:  # as before: a NaN inside an array raises (allow_nan=False)
        return json.dumps(content, default=_listed, ensure_ascii=False, allow_nan=False,
                          separators=(",", ":")).encode()
    return orjson.dumps(content, default=_default, option=_OPTIONS)


def npy_bytes(array: Any) -> bytes:
    """``array`` in NumPy's ``.npy`` format (float64 unless it is boolean or integer)."""
    a = np.asarray(array)
    if a.dtype.kind not in "biu":
        a = a.astype(np.float64, copy=False)
    buffer = io.BytesIO()
    np.save(buffer, np.ascontiguousarray(a), allow_pickle=False)
    return buffer.getvalue()


def wants_npy(request: Request) -> bool:
    """The client asked for the binary answer (``Accept`` names ``application/x-npy``)."""
    return NPY_MEDIA_TYPE in request.headers.get("accept", "").lower()


def answer(body: bytes, npy: bool = False) -> Response:
    """A response carrying encoded ``body``: ``.npy`` bytes or JSON."""
    return Response(body, media_type=NPY_MEDIA_TYPE if npy else "application/json")


#: OpenAPI entry of the binary answer, for a route's ``responses``.
NPY_RESPONSE: dict[int | str, dict[str, Any]] = {
    200: {"content": {NPY_MEDIA_TYPE: {"schema": {"type": "string", "format": "binary"}}},
          "description": "JSON; with `Accept: application/x-npy` the main array as .npy"},
}


#: Deepest nesting of arrays and objects a JSON body may have (orjson's own limit; the
#: deepest document the API takes is a few levels).
MAX_JSON_DEPTH = 1024


def _too_deep(text: bytes | str, pos: int = 0) -> json.JSONDecodeError:
    doc = text if isinstance(text, str) else text[:200].decode("utf-8", "replace")
    return json.JSONDecodeError(f"arrays and objects nested deeper than {MAX_JSON_DEPTH} "
                                "levels", doc, min(pos, len(doc)))


def loads_json(body: bytes | str) -> Any:
    """JSON ``body`` decoded by orjson, or by the standard library where orjson refuses it
    (``NaN`` and ``Infinity`` tokens); the one reader of JSON that comes with a request.
    ``json.JSONDecodeError`` (a ``ValueError``) when neither reads it, nesting deeper than
    ``MAX_JSON_DEPTH`` included (the standard library would recurse until Python's stack
    limit instead)."""
    try:
        if legacy:
            return json.loads(body)
        try:
            return orjson.loads(body)
        except orjson.JSONDecodeError as exc:
            if "depth" in exc.msg:
                raise _too_deep(body, exc.pos) from None
            return json.loads(body)
    except RecursionError:
        raise _too_deep(body) from None



class _Missing:
    """No body was sent."""


MISSING = _Missing()


async def request_body(request: Request) -> tuple[bytes, Any]:
    """The raw body and its JSON (``MISSING`` when empty), for a route that reads its body
    itself; malformed JSON is the 422 FastAPI gives (``json_invalid`` at ``body``), a body
    that is not text its 400."""
    raw = await request.body()
    if not raw:
        return raw, MISSING
    try:
        return raw, loads_json(raw)
    except json.JSONDecodeError as exc:
        raise RequestValidationError([{
            "type": "json_invalid", "loc": ("body", exc.pos), "msg": "JSON decode error",
            "input": {}, "ctx": {"error": exc.msg}}]) from None
    except ValueError:  # not UTF-8, say: FastAPI's answer to a body it cannot read
        raise HTTPException(400, "There was an error parsing the body") from None


async def read_json(request: Request) -> Any:
    """The request's JSON body, decoded as ``request_body`` does."""
    return (await request_body(request))[1]


def validate_body(model: type[BaseModel], data: Any) -> Any:
    """``data`` validated as the body ``model``; the errors are those FastAPI gives for a
    body parameter (``loc`` starting with ``"body"``, a missing body at ``["body"]``)."""
    if data is MISSING:
        raise RequestValidationError([{"type": "missing", "loc": ("body",),
                                       "msg": "Field required", "input": None}])
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise RequestValidationError([{**e, "loc": ("body", *e["loc"])}
                                      for e in exc.errors(include_url=False)]) from None


def body_schema(model: type[BaseModel]) -> dict[str, Any]:
    """``openapi_extra`` publishing ``model`` as the request body of a route that reads its
    body itself (the model must have no nested definitions)."""
    schema = model.model_json_schema()
    if "$defs" in schema:
        raise ValueError(f"{model.__name__} has nested definitions; publish it as a parameter")
    return {"requestBody": {"required": True,
                            "content": {"application/json": {"schema": schema}}}}


class FastJSONResponse(JSONResponse):
    """``JSONResponse`` encoded by ``dumps`` (orjson)."""

    def render(self, content: Any) -> bytes:
        return dumps(content)


class FastJSONRequest(Request):
    """A request whose JSON body orjson decodes (the standard library when orjson refuses
    it, e.g. ``NaN`` tokens, so the validation errors stay what they were)."""

    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            self._json = loads_json(await self.body())
        return self._json


class FastJSONRoute(APIRoute):
    """A route whose request body is decoded by ``FastJSONRequest``."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def route(request: Request) -> Response:
            return await handler(FastJSONRequest(request.scope, request.receive))

        return route
