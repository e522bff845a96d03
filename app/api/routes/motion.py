"""Joint-space motion planning of one robot in a scene, answered at once (``planning.motion``).

``POST /robots/{id}/motion`` plans one problem for up to ``MAX_SYNC_TIME_LIMIT_S`` seconds
in a compute worker (planning holds the interpreter for its whole time limit, so never in
the API's process). The robot's collision model and the scene are found as for collision
queries (``app.collision_models``) and kept by the worker between requests, sent to it only
when it lacks them (``run_kept``). The worker keeps the planner's checker prepared from them
too (the robot's and the scene's arrays for the compiled checks), lent to one request at a
time (``worker_prepared``). Longer searches and batches are ``motion`` jobs.

A body with ``steps`` in place of ``goal`` is a task (``planning.motion.task``): moves, lines
and arcs planned in turn from ``start`` within the one ``time_limit``, answered as one path
and one trajectory with a status per step.
"""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Request, Response
from pydantic import BeforeValidator, ConfigDict, Field, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from kinematics.model import RobotModel
from planning.motion.request import MotionRequest, robot_problem
from planning.motion.task import TaskRequest, robot_task

from ...collision_models import run_kept, worker_prepared
from ...compute import ComputePool, encode_json
from ...fields import JointVector
from ...jobs.motion_kinds import (
    STEPS_DESCRIPTION,
    GoalIn,
    MotionOut,
    MotionSettings,
    MotionTaskOut,
    StepsIn,
    motion_answer,
    warm_up,
)
from ...responses import FastJSONRoute
from ..common import collision_entry, resolve_scene
from ..deps import get_robot
from ..schemas import GLT_SWING, body_examples

router = APIRouter(prefix="/robots", tags=["motion"], route_class=FastJSONRoute)

#: Longest ``time_limit`` (s) of a synchronous motion request (422 above; jobs take 60 s).
MAX_SYNC_TIME_LIMIT_S = 2.0


class _GoalMissing:
    """Stands for an absent or null ``goal`` in a body without ``steps`` (``null``: the
    value given): its check answers what a required ``goal`` answered, among the other
    fields' errors, so a body without ``steps`` is answered as before ``steps`` existed."""

    def __init__(self, given: bool) -> None:
        self.given = given


def _not_missing(value: Any) -> Any:
    if isinstance(value, _GoalMissing):
        if value.given:
            raise PydanticCustomError("model_type", "Input should be a valid dictionary or "
                                      "instance of {class_name}", {"class_name": "GoalIn"})
        raise PydanticCustomError("missing", "Field required")
    return value


class MotionRequestBody(MotionSettings):
    model_config = ConfigDict(json_schema_extra=body_examples(GLT_SWING,
                                                              robot="glt_palletizer"))

    start: JointVector = Field(description="rad / mm per joint, in the robot's joint order (GET "
                       "/robots/{id})")
    goal: Annotated[GoalIn | None, BeforeValidator(_not_missing)] = Field(
        None, description="Where the move ends (required unless steps is given)")
    steps: StepsIn | None = Field(None, description=STEPS_DESCRIPTION)  # type: ignore[valid-type]
    time_limit: float = Field(MAX_SYNC_TIME_LIMIT_S, gt=0, le=MAX_SYNC_TIME_LIMIT_S,
                              description="s of planning (of the whole task, with steps); "
                              "longer searches are motion jobs")

    @model_validator(mode="before")
    @classmethod
    def _goal_or_steps(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("steps") is None and data.get("goal") is None:
            return {**data, "goal": _GoalMissing("goal" in data)}
        return data

    @model_validator(mode="after")
    def _not_both(self) -> MotionRequestBody:
        if self.steps is not None and self.goal is not None:
            # At the field (not the body): raised as the validation error it is.
            raise ValidationError.from_exception_data("MotionRequestBody", [
                {"type": PydanticCustomError("value_error", "give goal (one move) or steps "
                                             "(a task), not both"),
                 "loc": ("goal",), "input": None}])
        return self

    def request(self, model: Any) -> MotionRequest | TaskRequest:
        """The problem or the task, checked against the robot ``model`` (``FieldError``
        naming the field): the body is valid already, so only what depends on the robot (and
        a task's steps) is checked."""
        if self.steps is not None:
            return robot_task(model, self.start, self.steps, **self.planner_settings(),
                              scene=self.scene, time_limit=self.time_limit)
        return robot_problem(model, self.start, self.goal.as_goal(),
                             **self.planner_settings(), time_limit=self.time_limit)


class MotionAnswer(MotionOut):
    robot: str
    joints: list[str] = Field(description="The joint names, in the order of every q")


class MotionTaskAnswer(MotionTaskOut):
    """The answer to a body with ``steps``."""

    robot: str
    joints: list[str] = Field(description="The joint names, in the order of every q")


def _robot_model(cm: Any) -> Any:
    """The robot model a collision model was built from (an imported robot's: its model)."""
    return cm.source.model if cm.kind == "imported" else cm.source


def _reset(checker: Any) -> None:
    """Undo what a plan may leave set on a ``MotionChecker`` before the next request of the
    worker uses it: a checker answers as a new one would."""
    checker.deadline = None
    checker.exact = True
    checker.exact_zone = None
    checker.checks = checker.exact_checks = 0


def _plan(cm: Any, scene: Any, model: Any, cm_token: str | None, scene_token: str | None,
          req: Any) -> bytes:
    """Run in a compute worker (``run_kept``: the collision model and the scene are the ones
    the worker keeps): plan ``req`` with the checker the worker keeps for this model, scene
    and settings (prepared once: its robot and scene arrays), or a new one for a scene
    without a token (inline, naming a stored mesh). ``model`` None: the collision model's
    own."""
    model = _robot_model(cm) if model is None else model
    names = [j.name for j in model.joints]
    warm_up(req, cm, scene)
    key = None
    if cm_token is not None and (scene is None or scene_token is not None):
        key = ("motion", cm_token, scene_token, bool(req.self_collision), float(req.margin))
    with worker_prepared(key, lambda: req.checker(cm, scene), _reset) as checker:
        result = req.plan(checker, model)
    return encode_json({**motion_answer(result, names), "robot": model.id, "joints": names})


async def _robot(request: Request, robot_id: Annotated[str, Path(
        description="Robot id, e.g. 'glt_palletizer'")]) -> RobotModel:
    """``RobotDep``'s model (404 if unknown), found in the event loop: a dictionary lookup,
    not worth the thread pool's hop a synchronous dependency takes."""
    return get_robot(request.app.state.registry, robot_id)


@router.post("/{robot_id}/motion", response_model=MotionAnswer | MotionTaskAnswer,
             responses={404: {"description": "Unknown robot or scene"},
                        422: {"description": "A field that is wrong, named in loc"}})
async def plan_motion_now(robot: Annotated[RobotModel, Depends(_robot)],
                          body: MotionRequestBody, request: Request) -> Response:
    """Plan a collision-free joint-space move from ``start`` to ``goal`` (joint values or a
    tool pose) in a scene, or a task of ``steps`` (moves, lines, arcs) from ``start``; every
    status but ``ok`` is an answer too (200), not an error. A task's answer has the fields
    of a move's (over the whole path) and ``steps``."""
    req = body.request(robot)
    scene, scene_token = resolve_scene(request, body.scene)
    cm, cm_token = await collision_entry(request, request.app.state.registry, robot.id)
    pool: ComputePool = request.app.state.compute
    # The collision model's own robot model (the usual case) travels inside it: not sent.
    model = None if cm_token is not None and _robot_model(cm) is robot else robot
    data = await run_kept(pool, _plan, [(cm_token, cm), (scene_token, scene), (None, model)],
                          cm_token, scene_token, req)
    return Response(data, media_type="application/json")
