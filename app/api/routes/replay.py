"""A finished job's replay as one HTML file: ``GET /jobs/{id}/replay.html``.

The page plays the job's trajectory offline (saved to disk and opened in any browser): the
robot, its scene and the tool path, with a time slider, Play/Pause, orbit and zoom. What it
holds and how it is built: ``app.replay``; which kinds have a trajectory and the errors of
those without one: ``app.trajectory_export``. This module only translates HTTP (404 unknown
job, 409 not succeeded, 422 naming the query field or the job).
"""

from __future__ import annotations

from typing import Annotated, Any

import orjson
from fastapi import APIRouter, Path, Query, Request, Response
from pydantic import ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from planning.motion.request import MAX_PROBLEMS

from ...fields import StrictModel, joint_batch
from ...jobs.motion_kinds import SceneIn
from ...jobs.path_kinds import MAX_TRAJECTORY_SAMPLES
from ...replay import build_replay, replay_html
from ...responses import FastJSONRoute
from ...trajectory_export import ExportError
from ..common import resolve_scene, succeeded_job
from ..deps import RobotDep
from ..errors import http_error, invalid
from ..schemas import body_examples

__all__ = ["router", "motion_router"]

router = APIRouter(prefix="/jobs", tags=["jobs"])
motion_router = APIRouter(prefix="/robots", tags=["motion"], route_class=FastJSONRoute)

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


# ---- a motion answer posted back -----------------------------------------------------------
_SWING_T = [0.0, 0.5, 1.0, 1.5, 2.0]
_SWING_Q = [[-1.0 + 0.5 * k, 0.3, -0.3, 0.0, 0.5, 0.0] for k in range(5)]


class SampledIn(StrictModel):
    """The answer's ``trajectory``: what a replay reads of it (other fields are ignored)."""

    model_config = ConfigDict(extra="ignore")

    t: Annotated[list[Annotated[float, Field(ge=0.0, le=1e7)]],
                 Field(min_length=1, max_length=MAX_TRAJECTORY_SAMPLES)] = Field(
        description="Sample times, s, increasing")
    q: joint_batch(MAX_TRAJECTORY_SAMPLES) = Field(description="The joints at each time")

    @model_validator(mode="after")
    def _aligned(self) -> SampledIn:
        if len(self.q) != len(self.t):
            raise PydanticCustomError("value_error", "q has {q} rows, t {t} times",
                                      {"q": len(self.q), "t": len(self.t)})
        if any(len(row) != len(self.q[0]) for row in self.q):
            raise PydanticCustomError("value_error", "every row of q has as many values")
        if any(b <= a for a, b in zip(self.t, self.t[1:], strict=False)):
            raise PydanticCustomError("value_error", "t does not increase")
        return self


class AnswerIn(StrictModel):
    """A motion answer as ``POST /robots/{id}/motion`` gave it (other fields are ignored)."""

    model_config = ConfigDict(extra="ignore")

    robot: str | None = Field(None, max_length=128, description="The robot it was planned "
                              "for: the path's robot_id (checked when given)")
    trajectory: SampledIn = Field(description="The answer's timed trajectory (an answer "
                                  "planned with trajectory: false has none to replay)")


class MotionReplayBody(StrictModel):
    """A motion answer and the scene it was planned in."""

    model_config = ConfigDict(json_schema_extra=body_examples(
        {"answer": {"robot": "glt_palletizer", "status": "ok",
                    "trajectory": {"t": _SWING_T, "q": _SWING_Q}},
         "scene": {"objects": [{"type": "box", "id": "crate", "size": [400, 300, 250],
                                "pose": [[1, 0, 0, 1500], [0, 1, 0, 600], [0, 0, 1, 125],
                                         [0, 0, 0, 1]]}]}},
        robot="glt_palletizer"))

    answer: AnswerIn
    scene: SceneIn = Field(None, description="The scene the answer was planned in, as the "
                           "motion request gave it (a stored scene's id or inline objects); "
                           "default: none drawn")


@motion_router.post(
    "/{robot_id}/motion/replay.html", response_class=Response,
    responses={200: {"description": "One self-contained HTML page (no network needed)",
                     "content": {"text/html": {}}},
               404: {"description": "Unknown robot or stored scene"},
               422: {"description": "A field of the body that is wrong, named in loc"}})
def post_motion_replay(robot: RobotDep, body: MotionReplayBody, request: Request) -> Response:
    """A motion answer (of ``POST /robots/{robot_id}/motion``, posted back as ``answer``) as
    one HTML file that plays it offline, as ``GET /jobs/{id}/replay.html`` does for a job:
    the robot along the answer's ``trajectory``, the scene it was planned in, a time slider
    with Play/Pause, orbit and zoom."""
    answer = body.answer
    if answer.robot is not None and answer.robot != robot.id:
        raise invalid(["answer", "robot"], f"the answer was planned for '{answer.robot}', "
                      f"not '{robot.id}'")
    if len(answer.trajectory.q[0]) != robot.dof:
        raise invalid(["answer", "trajectory", "q"], f"rows of {len(answer.trajectory.q[0])} "
                      f"values; robot '{robot.id}' has {robot.dof} joints")
    scene, _ = resolve_scene(request, body.scene)
    registry = request.app.state.registry
    result: dict[str, Any] = {"robot": robot.id, "trajectory": answer.trajectory.model_dump()}
    try:
        replay = build_replay("posted", "motion", {"robot": robot.id}, result, registry.get,
                              registry.imported, scene=scene)
    except ExportError as exc:
        raise invalid(["answer", "trajectory"], exc.message) from None
    return Response(replay_html(replay), media_type="text/html; charset=utf-8", headers={
        "content-disposition": f'inline; filename="{robot.id}-motion-replay.html"'})
