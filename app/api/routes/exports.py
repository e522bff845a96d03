"""A finished job's joint trajectory as a file: ``GET /jobs/{id}/trajectory``.

``format=json`` (default: the service's units, stated per joint), ``csv`` (one row per
sample, header ``time_s,<joint>_pos...,<joint>_vel...,<joint>_acc...``) or
``joint_trajectory`` (ROS ``trajectory_msgs/JointTrajectory`` as JSON, rad and m). Which
kinds carry a trajectory and how each is read: ``app.trajectory_export``; this module only
translates HTTP (404 unknown job, 409 not succeeded, 422 naming the query field or the job).
"""

from __future__ import annotations

from typing import Annotated, Literal

import orjson
from fastapi import APIRouter, Path, Query, Request, Response

from planning.motion.request import MAX_PROBLEMS

from ...responses import FastJSONRoute, dumps
from ...trajectory_export import (
    ExportError,
    extract,
    select,
    to_csv,
    to_joint_trajectory,
    to_json,
)
from ..common import succeeded_job
from ..errors import http_error

__all__ = ["router"]

router = APIRouter(prefix="/jobs", tags=["jobs"], route_class=FastJSONRoute)

Format = Literal["json", "csv", "joint_trajectory"]
JobId = Annotated[str, Path(description="Job id", max_length=64)]


@router.get(
    "/{job_id}/trajectory", response_class=Response,
    responses={200: {"description": "The trajectory (a list of them for several arms or "
                     "problems, json and joint_trajectory only)",
                     "content": {"application/json": {}, "text/csv": {}}},
               404: {"description": "Unknown job"},
               409: {"description": "The job has not succeeded (its status is said)"},
               422: {"description": "A bad format, arm or problem, or a job whose kind or "
                     "result has no trajectory"}})
def get_job_trajectory(
    job_id: JobId,
    request: Request,
    fmt: Annotated[Format, Query(alias="format", description=(
        "json: s, rad, mm (stated per joint); csv: a header row time_s,<joint>_pos..., "
        "<joint>_vel..., <joint>_acc..., then one row per sample in the same units; "
        "joint_trajectory: ROS trajectory_msgs/JointTrajectory as JSON (rad, m)"))] = "json",
    arm: Annotated[str | None, Query(max_length=64, description=(
        "multiarm jobs: the arm (left, middle, right); without it json and "
        "joint_trajectory answer every arm, in a list"))] = None,
    problem: Annotated[int | None, Query(ge=0, le=MAX_PROBLEMS, description=(
        "motion jobs of several problems: the problem's index; without it json and "
        "joint_trajectory answer every solved problem, in a list"))] = None,
) -> Response:
    """The joint trajectory of a succeeded job: positions, velocities, accelerations and
    time from the start of every sample. Kinds: ``motion`` (a solved problem with its
    trajectory; each problem of a batch), ``path`` (planned for a robot), ``multiarm`` (one
    per arm) and ``tracking``; velocities and accelerations of the last two are estimated
    from their stored positions by finite differences (``derivatives`` in json)."""
    job, text = succeeded_job(request, job_id, "a trajectory")
    try:
        tracks = extract(job.kind, job.params, orjson.loads(text),
                         request.app.state.registry.get)
        chosen, several = select(job.kind, tracks, fmt, {"arm": arm, "problem": problem})
    except ExportError as exc:
        raise http_error(422, exc.loc, exc.message, "value_error") from None
    selector = tracks.selector
    if fmt == "csv":
        label, track = chosen[0]
        suffix = "" if selector is None else f"-{selector}-{label}"
        units = ",".join("mm" if p else "rad" for p in track.prismatic)
        return Response(to_csv(track), media_type="text/csv", headers={
            "content-disposition": f'attachment; filename="{job_id}-trajectory{suffix}.csv"',
            "x-joint-units": units})
    if fmt == "joint_trajectory":
        messages = [to_joint_trajectory(track) for _, track in chosen]
        body = ([{selector: label, "joint_trajectory": m}
                 for (label, _), m in zip(chosen, messages, strict=True)]
                if several else messages[0])
    else:
        body = [to_json(track, {"job": job_id, "kind": job.kind,
                                **({selector: label} if selector else {})})
                for label, track in chosen]
        body = body if several else body[0]
    return Response(dumps(body), media_type="application/json")
