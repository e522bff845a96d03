"""A finished round's drill plan written back with its schedule: ``GET /jobs/{id}/plan``.

The plan the ``round`` job was given — its IREDES plan (``plan_iredes``, in the plan's own
frame, as it came) or its list of holes (``holes``, as given, before ``rig_pose``) — with each
drilled hole's boom, its place in that boom's drilling order (1 first) and its planned start
(collaring starts) and end (retracted), s on the round's clock. ``format=iredes`` (default):
``planning.drilling.plans.write_iredes`` with the assignments in each hole's ``HoleOptions``
(``read_iredes_with_assignments`` reads them back; rigs ignore options they do not know);
``csv``: the plan's CSV columns and ``boom,order,start_s,end_s`` (empty for a hole not
drilled); ``json``: ``{"job", "plan": DrillPlan.to_json(), "assignments": {id: {...}},
"unreachable": [...]}``. This module only translates HTTP: 404 unknown job, 409 not succeeded,
422 at ``["query", "format"]`` or, for another kind of job, ``["path", "job_id"]``.
"""

from __future__ import annotations

import csv
import io
from typing import Annotated, Any, Literal

import orjson
from fastapi import APIRouter, Path, Query, Request, Response

from ...responses import FastJSONRoute, dumps
from ..common import succeeded_job
from ..errors import http_error

__all__ = ["router", "round_assignments", "round_drill_plan"]

router = APIRouter(prefix="/jobs", tags=["jobs"], route_class=FastJSONRoute)

Format = Literal["iredes", "csv", "json"]
JobId = Annotated[str, Path(description="Job id", max_length=64)]
#: Columns the CSV adds to the plan's own (``planning.drilling.plans.CSV_COLUMNS``).
SCHEDULE_COLUMNS = ("boom", "order", "start_s", "end_s")


def round_assignments(result: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """``{hole_id: {"boom", "order", "start_s", "end_s"}}`` of a round result: ``order`` is
    the hole's place (1 first) in its boom's ``holes``, the times its ``holes`` entry's."""
    places = {hid: k + 1 for boom in result["booms"].values()
              for k, hid in enumerate(boom["holes"])}
    return {h["id"]: {"boom": h["boom"], "order": places.get(h["id"], 0),
                      "start_s": float(h["start_s"]), "end_s": float(h["end_s"])}
            for h in result["holes"]}


def round_drill_plan(job_id: str, params: dict[str, Any]):
    """The drill plan a round job was given (``DrillPlan``): its IREDES plan as read, or
    its holes as a plan of id ``round-<job id>`` (identity frame, the holes' own frame)."""
    from planning.drilling.plans import DrillPlan, Hole, read_iredes

    if params.get("plan_iredes"):
        return read_iredes(params["plan_iredes"],
                           verify_checksum=params.get("plan_verify_checksum", True))
    import numpy as np

    holes = tuple(Hole(h["id"], "", h["collar"], h["toe"], h.get("type") or "")
                  for h in params["holes"])
    return DrillPlan(f"round-{job_id}", "", np.eye(4), "", holes)


def _csv(plan, assignments: dict[str, dict[str, Any]]) -> str:
    """The plan's CSV (``to_csv``) with the schedule's columns appended."""
    from planning.drilling.plans import to_csv

    rows = list(csv.reader(io.StringIO(to_csv(plan))))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*rows[0], *SCHEDULE_COLUMNS])
    for row in rows[1:]:
        a = assignments.get(row[0])
        writer.writerow([*row, *([a["boom"], a["order"], repr(a["start_s"]), repr(a["end_s"])]
                                 if a else ["", "", "", ""])])
    return out.getvalue()


@router.get(
    "/{job_id}/plan", response_class=Response,
    responses={200: {"description": "The drill plan with each drilled hole's boom, order and "
                     "planned start and end",
                     "content": {"application/xml": {}, "text/csv": {},
                                 "application/json": {}}},
               404: {"description": "Unknown job"},
               409: {"description": "The job has not succeeded (its status is said)"},
               422: {"description": "A bad format, or a job that is not a round"}})
def get_round_plan(
    job_id: JobId,
    request: Request,
    fmt: Annotated[Format, Query(alias="format", description=(
        "iredes: the IREDES drill plan (DRPPlan XML, metres, its checksum) with a "
        "kp:Assignment {boom, order, start_s, end_s} in each drilled hole's HoleOptions; "
        "csv: the plan's columns (mm) and boom, order, start_s, end_s; json: {job, plan, "
        "assignments, unreachable}"))] = "iredes",
) -> Response:
    """The drill plan of a succeeded ``round`` job written back with each drilled hole's
    boom, order (1 first, per boom) and planned start and end times (s)."""
    job, text = succeeded_job(request, job_id, "a drill plan")
    if job.kind != "round":
        raise http_error(422, ["path", "job_id"], f"job {job_id} is a {job.kind!r} job; "
                         "only a round job has a drill plan to write back", "value_error")
    from planning.drilling.plans import write_iredes

    result = orjson.loads(text)
    assignments = round_assignments(result)
    try:
        plan = round_drill_plan(job_id, job.params)
    except (ValueError, KeyError) as exc:
        raise http_error(422, ["path", "job_id"], f"job {job_id}: its drill plan cannot be "
                         f"read back ({exc})", "value_error") from None
    known = set(plan.ids())
    assignments = {k: v for k, v in assignments.items() if k in known}
    if fmt == "iredes":
        body = write_iredes(plan, assignments=assignments).encode("utf-8")
        return Response(body, media_type="application/xml", headers={
            "content-disposition": f'attachment; filename="{job_id}-plan.xml"'})
    if fmt == "csv":
        return Response(_csv(plan, assignments), media_type="text/csv", headers={
            "content-disposition": f'attachment; filename="{job_id}-plan.csv"'})
    return Response(dumps({"job": job_id, "plan": plan.to_json(), "assignments": assignments,
                           "unreachable": result.get("unreachable", [])}),
                    media_type="application/json")
