"""Joint-space motion planning of one robot in a scene, answered at once (``planning.motion``).

``POST /robots/{id}/motion`` plans one problem for up to ``MAX_SYNC_TIME_LIMIT_S`` seconds
in a compute worker (planning holds the interpreter for its whole time limit, so never in
the API's process). The robot's collision model and the scene are found as for collision
queries (``app.collision_models``) and kept by the worker between requests. Longer
searches and batches are ``motion`` jobs.
"""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request, Response
from pydantic import Field

from planning.motion.request import MotionRequest, robot_problem

from ...collision_models import worker_cached
from ...compute import ComputePool, encode_json
from ...fields import JointVector
from ...jobs.motion_kinds import GoalIn, MotionOut, MotionSettings, motion_answer, warm_up
from ...responses import FastJSONRoute
from ..common import collision_entry, resolve_scene
from ..deps import RegistryDep, RobotDep

router = APIRouter(prefix="/robots", tags=["motion"], route_class=FastJSONRoute)

#: Longest ``time_limit`` (s) of a synchronous motion request (422 above; jobs take 60 s).
MAX_SYNC_TIME_LIMIT_S = 2.0


class MotionRequestBody(MotionSettings):
    start: JointVector = Field(description="rad / mm per joint, in the robot's joint order (GET "
                       "/robots/{id})")
    goal: GoalIn
    time_limit: float = Field(MAX_SYNC_TIME_LIMIT_S, gt=0, le=MAX_SYNC_TIME_LIMIT_S,
                              description="s of planning; longer searches are motion jobs")

    def request(self, model: Any) -> MotionRequest:
        """The problem, checked against the robot ``model`` (``FieldError`` naming the
        field): the body is valid already, so only what depends on the robot is checked."""
        return robot_problem(model, self.start, self.goal.as_goal(),
                             **self.planner_settings(), time_limit=self.time_limit)


class MotionAnswer(MotionOut):
    robot: str
    joints: list[str] = Field(description="The joint names, in the order of every q")


def _plan(cm: Any, cm_token: str | None, scene: Any, scene_token: str | None, model: Any,
          req: Any) -> bytes:
    """Run in a compute worker: plan ``req`` with the (kept) collision model and scene."""
    cm = worker_cached(cm_token, cm)
    scene = worker_cached(scene_token, scene) if scene is not None else None
    names = [j.name for j in model.joints]
    warm_up(req, cm, scene)
    result = req.plan(req.checker(cm, scene), model)
    return encode_json({**motion_answer(result, names), "robot": model.id, "joints": names})


@router.post("/{robot_id}/motion", response_model=MotionAnswer,
             responses={404: {"description": "Unknown robot or scene"},
                        422: {"description": "A field that is wrong, named in loc"}})
async def plan_motion_now(robot: RobotDep, registry: RegistryDep, body: MotionRequestBody,
                          request: Request) -> Response:
    """Plan a collision-free joint-space move from ``start`` to ``goal`` (joint values or a
    tool pose) in a scene; every status but ``ok`` is an answer too (200), not an error."""
    req = body.request(robot)
    scene, scene_token = resolve_scene(request, body.scene)
    cm, cm_token = await collision_entry(request, registry, robot.id)
    pool: ComputePool = request.app.state.compute
    data = await pool.run(True, _plan, cm, cm_token, scene, scene_token, robot, req)
    return Response(data, media_type="application/json")
