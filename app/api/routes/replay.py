"""A finished job's replay as one HTML file: ``GET /jobs/{id}/replay.html``.

The page plays the job's trajectory offline (saved to disk and opened in any browser): the
robot, its scene and the tool path, with a time slider, Play/Pause, orbit and zoom. What it
holds and how it is built: ``app.replay``; which kinds have a trajectory and the errors of
those without one: ``app.trajectory_export``. This module only translates HTTP (404 unknown
job, 409 not succeeded, 422 naming the query field or the job).
"""

from __future__ import annotations

from typing import Annotated

import orjson
from fastapi import APIRouter, Path, Query, Request, Response

from planning.motion.request import MAX_PROBLEMS

from ...replay import build_replay, replay_html
from ...trajectory_export import ExportError
from ..common import succeeded_job
from ..errors import http_error

__all__ = ["router"]

router = APIRouter(prefix="/jobs", tags=["jobs"])

JobId = Annotated[str, Path(description="Job id", max_length=64)]


@router.get(
    "/{job_id}/replay.html", response_class=Response,
    responses={200: {"description": "One self-contained HTML page (no network needed)",
                     "content": {"text/html": {}}},
               404: {"description": "Unknown job"},
               409: {"description": "The job has not succeeded (its status is said)"},
               422: {"description": "A bad arm or problem, or a job whose kind or result "
                     "has no trajectory"}})
def get_job_replay(
    job_id: JobId,
    request: Request,
    arm: Annotated[str | None, Query(max_length=64, description=(
        "multiarm jobs: show this arm only (left, middle, right); default: every arm"))] = None,
    problem: Annotated[int | None, Query(ge=0, le=MAX_PROBLEMS, description=(
        "motion jobs of several problems: the problem's index; default: the first solved "
        "one"))] = None,
) -> Response:
    """A succeeded job's motion as one HTML file that plays it offline in any browser: the
    robot (its own meshes when imported with them, else solids along its links), the scene
    it planned in, the tool path, a time slider with Play/Pause, orbit (drag) and zoom
    (wheel). Kinds: those with a trajectory (``GET /jobs/{id}/trajectory``): ``motion``,
    ``path`` (planned for a robot), ``multiarm`` (every arm) and ``tracking``."""
    job, text = succeeded_job(request, job_id, "a replay")
    registry = request.app.state.registry
    try:
        replay = build_replay(job_id, job.kind, job.params, orjson.loads(text), registry.get,
                              registry.imported, arm=arm, problem=problem)
    except ExportError as exc:
        raise http_error(422, exc.loc, exc.message, "value_error") from None
    except (KeyError, ValueError) as exc:  # a robot or scene changed since the job ran
        raise http_error(422, ["path", "job_id"], f"the job's result cannot be replayed: "
                         f"{exc}", "value_error") from None
    return Response(replay_html(replay), media_type="text/html; charset=utf-8", headers={
        "content-disposition": f'inline; filename="{job_id}-replay.html"'})
