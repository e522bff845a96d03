"""Drill plans in and out: IREDES (``DRPPlan``), CSV and JSON, stateless.

``POST /drill-plans/read`` takes a plan file as the body and answers it as JSON (mm);
``POST /drill-plans/write`` takes that JSON (optionally with each hole's boom, order and
times) and answers the file. The readers and writers are ``planning.drilling.plans``; its
``PlanFormatError`` names the element, CSV row and column, or JSON field at fault and is
answered 422 at ``["body", *loc]`` by the service's ``FieldError`` handler (413 for a plan
over ``MAX_HOLES`` holes). Bodies over ``HEAVY_BYTES`` are read in a compute worker.
"""

from __future__ import annotations

import re
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Query, Request, Response
from pydantic import BaseModel, Field

from planning.drilling.plans import (
    MAX_HOLES,
    DrillPlan,
    Hole,
    PlanTooLargeError,
    read_csv,
    read_iredes_with_assignments,
    read_json,
    to_csv,
    write_iredes,
)

from ...compute import encode_json
from ...responses import loads_json
from ..errors import invalid, too_large

router = APIRouter(prefix="/drill-plans", tags=["drill plans"])

#: Bodies larger than this (about 1,900 holes as IREDES, 10,000 as JSON: under a second
#: to read) are read or written in a compute worker process, not in the API's.
HEAVY_BYTES = 1024 * 1024

#: Content types of ``POST /drill-plans/read`` bodies and the format each means.
READ_CONTENT_TYPES = {"application/xml": "iredes", "text/xml": "iredes", "text/csv": "csv",
                      "application/json": "json"}


# ---- OpenAPI: shapes and examples ---------------------------------------------------------
class HoleOut(BaseModel):
    id: str
    name: str
    collar: list[float] = Field(description="x, y, z (mm), site frame")
    toe: list[float] = Field(description="x, y, z (mm), site frame")
    type: str
    diameter_mm: float | None


class AssignmentOut(BaseModel):
    boom: str | None = None
    order: int | None = None
    start_s: float | None = None
    end_s: float | None = None


class DrillPlanOut(BaseModel):
    plan_id: str
    name: str
    frame_name: str
    frame: list[list[float]] = Field(description="4x4 (rows), translation in mm")
    holes: list[HoleOut]
    hole_count: int
    assignments: dict[str, AssignmentOut] = Field(
        description="hole id -> boom, order, start_s, end_s, as found in the holes' "
        "HoleOptions (IREDES files written with assignments); {} otherwise")


_EXAMPLE_PLAN = DrillPlan(
    "R-0001", "Example round", [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]],
    "site",
    (Hole("1", "C001", [9000.0, -1200.0, 300.0], [13500.0, -1400.0, 300.0], "Contour", 45.0),
     Hole("2", "K001", [9000.0, 0.0, 1500.0], [13700.0, 0.0, 1500.0], "Cut", 45.0)))
_EXAMPLE_JSON = _EXAMPLE_PLAN.to_json()
_EXAMPLE_XML = write_iredes(_EXAMPLE_PLAN, created="2026-01-01T00:00:00")
_EXAMPLE_CSV = to_csv(_EXAMPLE_PLAN)

_NUMBER = {"type": "number"}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
_HOLE_SCHEMA = {
    "type": "object", "additionalProperties": False, "required": ["id", "collar", "toe"],
    "properties": {
        "id": {"type": "string", "minLength": 1, "maxLength": 200},
        "name": {"type": "string", "maxLength": 200},
        "collar": _VEC3, "toe": _VEC3,
        "type": {"type": "string", "maxLength": 200},
        "diameter_mm": {"anyOf": [_NUMBER, {"type": "null"}]},
    },
}
_ASSIGNMENT_SCHEMA = {
    "type": "object", "additionalProperties": False,
    "properties": {"boom": {"type": "string"}, "order": {"type": "integer"},
                   "start_s": _NUMBER, "end_s": _NUMBER},
}
_PLAN_SCHEMA: dict[str, Any] = {
    "type": "object", "additionalProperties": False, "required": ["plan_id", "holes"],
    "properties": {
        "plan_id": {"type": "string", "minLength": 1, "maxLength": 200},
        "name": {"type": "string", "maxLength": 200},
        "frame_name": {"type": "string", "maxLength": 200},
        "frame": {"type": "array", "minItems": 4, "maxItems": 4,
                  "items": {"type": "array", "items": _NUMBER, "minItems": 4, "maxItems": 4}},
        "holes": {"type": "array", "items": _HOLE_SCHEMA, "maxItems": MAX_HOLES},
        "hole_count": {"type": "integer"},
    },
}
_WRITE_SCHEMA: dict[str, Any] = {
    **_PLAN_SCHEMA,
    "properties": {**_PLAN_SCHEMA["properties"],
                   "assignments": {"type": "object",
                                   "additionalProperties": _ASSIGNMENT_SCHEMA}},
}
_READ_DOC = {"requestBody": {
    "required": True,
    "description": "The plan file: IREDES XML, CSV (header id, name, collar_x, collar_y, "
    "collar_z, toe_x, toe_y, toe_z, type, diameter_mm; mm) or the plan JSON; at most "
    f"{MAX_HOLES:,} holes",
    "content": {
        "application/xml": {"schema": {"type": "string"}, "example": _EXAMPLE_XML},
        "text/csv": {"schema": {"type": "string"}, "example": _EXAMPLE_CSV},
        "application/json": {"schema": _PLAN_SCHEMA, "example": _EXAMPLE_JSON},
    },
}}
_WRITE_DOC = {"requestBody": {
    "required": True,
    "description": "The plan JSON (as POST /drill-plans/read answers it), optionally with "
    "assignments: hole id -> {boom, order, start_s, end_s} (IREDES only)",
    "content": {"application/json": {"schema": _WRITE_SCHEMA, "example": {
        **_EXAMPLE_JSON,
        "assignments": {"1": {"boom": "left", "order": 1, "start_s": 0.0, "end_s": 95.5},
                        "2": {"boom": "right", "order": 1, "start_s": 0.0, "end_s": 101.0}},
    }}},
}}


# ---- the work (in the thread pool, or a compute worker for large bodies) -------------------
def _read_answer(data: bytes, fmt: str, verify_checksum: bool, northing_in_x: bool) -> bytes:
    """The plan in ``data`` as the encoded answer JSON."""
    assignments: dict[str, dict[str, Any]] = {}
    if fmt == "iredes":
        plan, assignments = read_iredes_with_assignments(
            data, verify_checksum=verify_checksum, northing_in_x=northing_in_x)
    elif fmt == "csv":
        plan = read_csv(data)
    else:
        try:
            obj = loads_json(data)
        except (ValueError, RecursionError) as exc:
            raise invalid([], f"body is not valid JSON: {exc}") from None
        if isinstance(obj, dict):
            obj = {k: v for k, v in obj.items() if k != "assignments"}
        plan = read_json(obj)
    return encode_json({**plan.to_json(), "hole_count": len(plan.holes),
                        "assignments": assignments})


def _write_answer(data: bytes, fmt: str, northing_in_x: bool) -> tuple[bytes, str]:
    """The plan JSON in ``data`` as the file's bytes, and the plan's id."""
    try:
        obj = loads_json(data)
    except (ValueError, RecursionError) as exc:
        raise invalid([], f"body is not valid JSON: {exc}") from None
    if not isinstance(obj, dict):
        raise invalid([], "a drill plan is a JSON object")
    assignments = obj.pop("assignments", None)
    plan = read_json(obj)
    if fmt == "csv":
        if assignments:
            raise invalid(["assignments"], "assignments are written to IREDES files only "
                          "(format=iredes)")
        return to_csv(plan).encode(), plan.plan_id
    text = write_iredes(plan, assignments=assignments, northing_in_x=northing_in_x)
    return text.encode(), plan.plan_id


def _format_of(request: Request, fmt: str | None) -> str:
    if fmt is not None:
        return fmt
    ctype = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if ctype in READ_CONTENT_TYPES:
        return READ_CONTENT_TYPES[ctype]
    if ctype.endswith("+xml"):
        return "iredes"
    raise invalid([], "say the body's format: content-type application/xml, text/csv or "
                  "application/json, or ?format=iredes|csv|json")


async def _run(request: Request, heavy: bool, fn, *args) -> Any:
    try:
        return await request.app.state.compute.run(heavy, fn, *args)
    except PlanTooLargeError as exc:
        raise too_large(list(exc.loc), exc.message) from None


def _filename(plan_id: str, suffix: str) -> str:
    return (re.sub(r"[^A-Za-z0-9._-]", "_", plan_id)[:100] or "plan") + suffix


@router.post(
    "/read", response_class=Response, openapi_extra=_READ_DOC,
    responses={200: {"model": DrillPlanOut, "description": "The plan, mm"},
               413: {"description": f"Body over its cap, or more than {MAX_HOLES:,} holes"},
               422: {"description": "Not a readable plan: the element, CSV row and column, "
                                    "or JSON field at fault is named in loc (a checksum "
                                    "mismatch at [\"body\", \"GenTrailer\", \"ChkSum\"])"}},
)
async def read_plan(
    request: Request,
    fmt: Annotated[Literal["iredes", "csv", "json"] | None, Query(
        alias="format", description="Default: from the content type (application/xml: "
        "iredes, text/csv: csv, application/json: json)")] = None,
    verify_checksum: Annotated[bool, Query(description="IREDES: check IR:ChkSum (CRC32 of "
                                           "the file with 0 in its place)")] = True,
    northing_in_x: Annotated[bool, Query(description="IREDES: the file has northing in "
                                         "PointX (x and y swapped)")] = False,
) -> Response:
    """Read a drill plan file (IREDES ``DRPPlan``, CSV or JSON) and answer it as JSON:
    holes with collar and toe in mm in the plan's site frame, the plan's frame, the hole
    count, and (IREDES) the assignments found in the holes' options."""
    fmt_ = _format_of(request, fmt)
    data = await request.body()
    answer = await _run(request, len(data) > HEAVY_BYTES, _read_answer, data, fmt_,
                        verify_checksum, northing_in_x)
    return Response(answer, media_type="application/json")


@router.post(
    "/write", response_class=Response, openapi_extra=_WRITE_DOC,
    responses={200: {"description": "The plan file: IREDES XML (metres, CRLF, IR:ChkSum) "
                                    "or CSV (mm)",
                     "content": {"application/xml": {}, "text/csv": {}}},
               413: {"description": f"Body over its cap, or more than {MAX_HOLES:,} holes"},
               422: {"description": "Invalid plan or assignment; the field at fault named"}},
)
async def write_plan(
    request: Request,
    fmt: Annotated[Literal["iredes", "csv"], Query(alias="format")] = "iredes",
    northing_in_x: Annotated[bool, Query(description="IREDES: write northing (y) in "
                                         "PointX")] = False,
) -> Response:
    """Write a drill plan (its JSON, mm) as an IREDES ``DRPPlan`` file or as CSV.
    ``assignments`` (IREDES only: hole id -> ``boom``, ``order``, ``start_s``, ``end_s``)
    go into each hole's ``HoleOptions`` (docs/drilling.md, "Drill plans")."""
    data = await request.body()
    body, plan_id = await _run(request, len(data) > HEAVY_BYTES, _write_answer, data, fmt,
                               northing_in_x)
    suffix, media = (".csv", "text/csv") if fmt == "csv" else (".xml", "application/xml")
    return Response(body, media_type=media, headers={
        "content-disposition": f'attachment; filename="{_filename(plan_id, suffix)}"'})
