"""Job kind ``motion``: joint-space motion planning of a robot in a scene (``planning.motion``),
one problem or a batch of them sharing the robot, the scene and the planner settings.

The body is that of ``POST /robots/{id}/motion`` plus ``robot``, with ``time_limit`` up to
60 s per problem, and ``problems`` (at most 1,000 ``{start, goal, seed?, time_limit?}``) in
place of ``start`` and ``goal`` for a batch, or ``steps`` (a task, ``planning.motion.task``:
at most ``MAX_TASK_STEPS`` moves, lines and arcs planned in turn from ``start``) in place of
``goal``. The models here (goal, shared settings, one
problem's result) are the route's too.

At submission (``prepare_motion``, the kind's ``prepare`` hook, called by the job manager
before the params are validated) the job gets everything its worker cannot look up: a
stored scene named by id becomes its objects inline (stored meshes with their vertices),
so the job's params record the geometry it planned in; and the params are checked against
the robot (joint counts, goal pose), so a wrong problem is a 422 naming it, not a failed
job. A worker has the robot's model, not the service's store: built-in and JSON robots
plan with the collision model built from the model (a capsule per link); for an imported
robot (``needs_geometry``) the job's payload carries its description, its stored collision
model and its collision meshes (``JobPayload.robot_files``), rebuilt once per worker
process.

A batch of more than ``MOTION_PART_PROBLEMS`` problems divides (``motion_graph``): that many
problems per step, each step planning them in turn with a checker of its own, and a step
that gathers them and sums them up. A plan depends on the problem, its seed and the shared
settings, not on what the checker planned before, so the answer is the one of a single
checker, except where planning is timed: the measured times always, and a problem that the
search solves only near its time limit (or not at all) or, with ``auto`` and a time limit
past 10 s, the RRT* refinement (these depend on the machine's speed in one process too).
"""

from __future__ import annotations

import json
import statistics
from collections.abc import Mapping
from typing import Annotated, Any, Literal

from pydantic import (
    Field,
    JsonValue,
    ValidationError,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import PydanticCustomError

from kinematics.errors import FieldError
from planning.motion import (
    DEFAULT_RESOLUTION,
    MAX_RESOLUTION,
    MIN_RESOLUTION,
    PLANNERS,
    MotionStatus,
)
from planning.motion.request import (
    DEFAULT_TIME_LIMIT_S,
    MAX_MARGIN_MM,
    MAX_PROBLEMS,
    MAX_TIME_LIMIT_S,
    MotionRequest,
    robot_problem,
)
from planning.motion.task import MAX_TASK_STEPS, TASK_STATUSES, TaskRequest, robot_task

from ..fields import JointVector, StrictModel, bounded_list, pose_type
from .caps import ParamsLimitError
from .graph import Ref, Step, run_inline
from .kinds import (
    MAX_SEED,
    JobKind,
    Params,
    Progress,
    Result,
    Submission,
    absent_when_none,
    pick,
    register,
)

__all__ = [
    "GoalIn",
    "MotionSettings",
    "StepsIn",
    "STEPS_DESCRIPTION",
    "ProblemIn",
    "MotionParams",
    "MotionTrajectoryOut",
    "MotionOut",
    "StepOut",
    "MotionTaskOut",
    "MotionSummary",
    "MotionJobResult",
    "MAX_MOTION_PARAMS_BYTES",
    "SCENE_KEYS",
    "collision_scene",
    "motion_answer",
    "warm_up",
    "summarize",
    "prepare_motion",
    "check_motion",
    "run_motion",
    "motion_graph",
    "MOTION_PART_PROBLEMS",
]

#: The planners (``planning.motion.PLANNERS``).
Planner = Literal[PLANNERS]  # type: ignore[valid-type]
#: How planning ended (``planning.motion.MotionStatus``).
Status = Literal[tuple(s.value for s in MotionStatus)]  # type: ignore[valid-type]
#: Most bytes of JSON a motion job's params take, a stored scene filled in included (413).
MAX_MOTION_PARAMS_BYTES = 4 * 1024 * 1024
#: Keys of an inline scene (``id``: the stored scene it was filled in from).
SCENE_KEYS = ("objects", "moveit", "name", "id")
#: Longest scene id.
MAX_SCENE_ID = 64

#: The settings of a ``MotionRequest`` besides its endpoints and scene.
_PLANNER_SETTINGS = ("planner", "seed", "resolution", "simplify", "self_collision",
                     "margin", "trajectory")

SceneIn = Annotated[str, Field(min_length=1, max_length=MAX_SCENE_ID)] | dict[str, Any] | None

#: A task's steps: objects checked by ``planning.motion.task`` (each by its ``type``), so an
#: error names the step and its field (``["body", "steps", 3, "target"]``).
StepsIn = bounded_list(dict[str, JsonValue], MAX_TASK_STEPS, min_length=1)
STEPS_DESCRIPTION = (
    f"A task, in place of goal: at most {MAX_TASK_STEPS} steps planned in turn from start, "
    "each from where the one before ended: {\"type\": \"move\", \"goal\": {\"q\"|\"pose\"}, "
    "\"planner\"?, \"time_limit\"?, \"seed\"?, \"simplify\"?} (joint space); {\"type\": "
    "\"line\", \"target\": 4x4 pose | [x, y, z] mm, \"orientation\"?: \"slerp\"|\"hold\", "
    "\"max_step\"?: mm, \"max_rotation\"?: rad, \"jump_threshold\"?: rad, \"time_limit\"?} "
    "(the tool along a straight line); {\"type\": \"arc\", \"via\" and \"target\", or "
    "\"centre\", \"axis\" and \"angle\", \"orientation\"?: \"slerp\"|\"hold\"|\"rotate\", ...} "
    "(the tool along a circular arc); {\"type\": \"attach\", \"object\": {a box, sphere, "
    "cylinder, capsule or mesh with its id}, \"link\"?, \"pose\"?, \"touch_links\"?} (carried "
    "from there on); {\"type\": \"detach\", \"object\": id, \"place\"?: true}; a move may "
    "keep \"constraints\": [...] (axis, orientation, position_line, position_plane, "
    "joint_range). time_limit bounds the whole task")


def _scene_description(stored: str) -> str:
    return ("A stored scene's id" + stored + ", an inline scene ({\"objects\": [...]} and/or "
            "{\"moveit\": {...}}, mm), or null (self-collision only)")


class GoalIn(StrictModel):
    """Where the move ends: joint values ``q`` or the tool pose ``pose`` (exactly one)."""

    q: JointVector | None = Field(None, description="rad / mm per joint, the robot's order")
    pose: pose_type(4) | None = Field(  # type: ignore[valid-type]
        None, description="T_world_tool, 4x4 (mm): the planner picks the IK branch")

    @model_validator(mode="after")
    def _one(self) -> GoalIn:
        if (self.q is None) == (self.pose is None):
            raise ValueError('give exactly one of "q" (joint values) and "pose" (the tool '
                             "pose, 4x4 mm)")
        return self

    def as_goal(self) -> dict[str, Any]:
        """The goal as ``planning.motion.request.robot_problem`` takes it."""
        return {"q": self.q} if self.q is not None else {"pose": self.pose}


class MotionSettings(StrictModel):
    """What a motion request and a motion job share: the scene and the planner's settings."""

    scene: SceneIn = Field(None, description=_scene_description(""))
    planner: Planner = Field("auto", description="'rrt_connect': the first path found, "
                             "shortened; 'rrt_star': keeps improving for the whole "
                             "time_limit; 'auto': RRT-Connect, refined by RRT* when the "
                             "time limit is long")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    resolution: float = Field(DEFAULT_RESOLUTION, ge=MIN_RESOLUTION, le=MAX_RESOLUTION,
                              description="Largest joint step between checked states along "
                              "an edge, rad (x 100 mm for prismatic joints); at least "
                              f"{MIN_RESOLUTION:g} rad ({MIN_RESOLUTION * 100:g} mm)")
    simplify: bool = Field(True, description="Shortcut and smooth the path found")
    self_collision: bool = Field(True, description="Check the robot against itself too")
    margin: float = Field(0.0, ge=0, le=MAX_MARGIN_MM,
                          description="mm: closer than this counts as a collision")
    trajectory: bool = Field(True, description="Time the path (time-optimal within the "
                             "robot's joint limits)")

    def planner_settings(self) -> dict[str, Any]:
        """The validated settings a ``MotionRequest`` takes (the scene is resolved apart;
        ``time_limit``, whose bound differs, is the request's or the job's own field)."""
        return {name: getattr(self, name) for name in _PLANNER_SETTINGS}


class ProblemIn(StrictModel):
    """One problem of a batch; ``seed`` and ``time_limit`` default to the job's."""

    start: JointVector
    goal: GoalIn
    seed: int | None = Field(None, ge=0, le=MAX_SEED)
    time_limit: float | None = Field(None, gt=0, le=MAX_TIME_LIMIT_S, description="s")


def _field_error(loc: str, kind: str, message: str) -> ValidationError:
    """An error of a check across fields, at the field it names (not at the model)."""
    return ValidationError.from_exception_data("MotionParams", [
        {"type": PydanticCustomError(kind, message), "loc": (loc,), "input": None}])


class MotionParams(Params, MotionSettings):
    """A motion job: ``start`` and ``goal``, or ``problems``."""

    robot: str = Field(max_length=200, description="Robot id")
    scene: SceneIn = Field(None, description=_scene_description(
        " (filled in with its objects when the job is submitted)"))
    start: JointVector | None = Field(None, description="rad / mm per joint (one problem)")
    goal: GoalIn | None = Field(None, description="One problem's goal")
    steps: StepsIn | None = absent_when_none(STEPS_DESCRIPTION)  # type: ignore[valid-type]
    problems: bounded_list(ProblemIn, MAX_PROBLEMS, min_length=1) | None = Field(  # type: ignore[valid-type]
        None, description=f"A batch: at most {MAX_PROBLEMS:,} problems, in place of start "
        "and goal")
    time_limit: float = Field(DEFAULT_TIME_LIMIT_S, gt=0, le=MAX_TIME_LIMIT_S,
                              description="s of planning per problem")

    @field_validator("scene")
    @classmethod
    def _scene_builds(cls, v: Any) -> Any:
        if isinstance(v, dict):
            collision_scene(v)
        return v

    @model_validator(mode="after")
    def _one_or_many(self) -> MotionParams:
        if self.steps is not None:
            if self.problems is not None:
                raise _field_error("steps", "value_error", "give steps (a task from start) "
                                   "or problems (a batch of moves), not both")
            if self.goal is not None:
                raise _field_error("goal", "value_error", "give goal (one move) or steps (a "
                                   "task), not both")
            if self.start is None:
                raise _field_error("start", "missing", "start is required (the task's "
                                   "first configuration)")
        elif self.problems is None:
            for name in ("start", "goal"):
                if getattr(self, name) is None:
                    raise _field_error(name, "missing", f"{name} is required (or give "
                                       "problems)")
        else:
            for name in ("start", "goal"):
                if getattr(self, name) is not None:
                    raise _field_error(name, "value_error", "give start and goal, or "
                                       "problems (each with its own start and goal), not both")
        return self

    def requests(self, model: Any) -> list[MotionRequest | TaskRequest]:
        """The problems checked against ``model`` (``FieldError`` naming the field): the
        params are valid already, so only what depends on the robot is checked
        (``robot_problem``); a task's steps are checked here (``robot_task``)."""
        shared = {**self.planner_settings(), "time_limit": self.time_limit}
        if self.steps is not None:
            return [robot_task(model, self.start, self.steps, **shared)]
        if self.problems is None:
            return [robot_problem(model, self.start, self.goal.as_goal(), **shared)]
        return [robot_problem(model, p.start, p.goal.as_goal(), loc=("problems", i),
                              **{**shared,
                                 "seed": shared["seed"] if p.seed is None else p.seed,
                                 "time_limit": (shared["time_limit"] if p.time_limit is None
                                                else p.time_limit)})
                for i, p in enumerate(self.problems)]


# ---- results ----------------------------------------------------------------------------
class MotionTrajectoryOut(Result):
    """The path timed within the robot's joint limits, sampled evenly."""

    t: list[float] = Field(description="s")
    q: list[list[float]] = Field(description="rad / mm per sample")
    qd: list[list[float]] = Field(description="rad/s / mm/s per sample")
    qdd: list[list[float]] = Field(description="rad/s² / mm/s² per sample")
    duration: float = Field(description="s")


Pair = Annotated[list[str], Field(min_length=2, max_length=2)]


class MotionOut(Result):
    """One problem's outcome (``planning.motion.MotionResult.to_dict``)."""

    status: Status = Field(description="ok, start_in_collision, goal_in_collision, "
                           "goal_unreachable, out_of_limits, no_path or timeout")
    message: str
    path: list[list[float]] = Field(description="Waypoints, rad / mm per joint; empty unless "
                                    "ok. Every straight segment between them is free")
    length: float | None = Field(description="Joint-space length of the path")
    planning_time_s: float = Field(description="Search and simplification, s")
    simplify_time_s: float
    min_clearance: float | None = Field(description="Least clearance along the path, mm")
    goal: list[float] | None = Field(description="The goal configuration reached (for a goal "
                                     "pose: the IK branch chosen)")
    pairs: list[Pair] = Field(description="Colliding pairs (link, object id or link) when the "
                              "start or the goal collides")
    planner: str = Field(description="The planner that ran")
    resolution: float = Field(description="Joint step of the checks along the path, rad")
    stats: dict[str, JsonValue] = Field(
        description="Search statistics: states checked (checks, exact_checks), tree nodes, "
        "iterations, raw_waypoints, raw_length, ...")
    trajectory: MotionTrajectoryOut | None


#: How a task or one of its steps ended: a move's statuses and a Cartesian segment's.
TaskStatus = Literal[TASK_STATUSES]  # type: ignore[valid-type]


class StepOut(Result):
    """How one step of a task ended (``planning.motion.task.StepResult.to_dict``)."""

    index: int = Field(description="The step's place in steps")
    type: str = Field(description="move, line, arc, attach or detach")
    status: TaskStatus = Field(description="A move's (ok, start_in_collision, "
                               "goal_in_collision, goal_unreachable, out_of_limits, no_path, "
                               "timeout) or a segment's (ok, unreachable, out_of_limits, "
                               "discontinuous, collision, timeout)")
    message: str
    states: list[int] = Field(min_length=2, max_length=2, description="[first, last]: the "
                              "step's states in the task's path, both included (first is the "
                              "previous step's last)")
    fraction: float | None = Field(description="A line or an arc: the share of its length "
                                   "reached (null for a move)")
    planner: str = Field(description="What planned it: the move's planner, line or arc")
    planning_time_s: float
    pairs: list[Pair] = Field(description="Colliding pairs (link, object id or link)")
    deviation: float | None = Field(description="A line or an arc: the tool's worst distance "
                                    "from the ideal curve between two states, mm")
    goal: list[float] | None = Field(description="A move: the goal configuration reached")


class MotionTaskOut(MotionOut):
    """A task's outcome (``planning.motion.task.TaskResult.to_dict``): the fields of one
    move's, over the whole path, and ``steps``."""

    status: TaskStatus = Field(description="One move: ok, start_in_collision, "
                               "goal_in_collision, goal_unreachable, out_of_limits, no_path or "
                               "timeout. A task: ok, or the status of the first step that "
                               "failed (planning stopped there), a move's or a line's or an "
                               "arc's (unreachable, discontinuous, collision, ...)")
    path: list[list[float]] = Field(description="Waypoints, rad / mm per joint; one move: "
                                    "empty unless ok. A task: the states of the steps planned "
                                    "from start, a failing step's up to where it stopped")
    length: float | None = Field(description="Joint-space length of the path")
    steps: list[StepOut] = Field(description="One per step planned, up to the first that "
                                 "failed")


class MotionSummary(Result):
    solved: int = Field(description="Problems with status ok")
    total: int
    median_planning_time_s: float | None = Field(description="Over all problems")
    median_length: float | None = Field(description="Over the solved problems")


class _OneOrMany(Result):
    """Result of one problem (its fields) or of a batch (``problems`` and ``summary``): the
    JSON carries the fields of the one it is."""

    @model_validator(mode="after")
    def _complete(self) -> _OneOrMany:
        batch = getattr(self, "problems", None) is not None
        if batch != (getattr(self, "summary", None) is not None):
            raise ValueError("problems and summary come together")
        if not batch and getattr(self, "status", None) is None:
            raise ValueError("a result has status (one problem) or problems (a batch)")
        return self

    @model_serializer(mode="wrap")
    def _fields_of_its_form(self, handler: Any):  # no return type: the schema stays the model's
        data = handler(self)
        if getattr(self, "problems", None) is None:
            drop = ("problems", "summary") + (("steps",) if data.get("steps") is None else ())
            return {k: v for k, v in data.items() if k not in drop}
        return {k: v for k, v in data.items() if k not in MotionTaskOut.model_fields}


#: The result of a motion job: ``robot``, ``joints`` and, for one problem, the fields of
#: ``MotionOut`` (of ``MotionTaskOut`` for a task, ``steps`` included); for a batch,
#: ``problems`` (one ``MotionOut`` each, in order) and ``summary``.
MotionJobResult = create_model(  # type: ignore[call-overload]
    "MotionJobResult",
    __base__=_OneOrMany,
    __doc__=(_OneOrMany.__doc__ or "") + " ``robot`` and ``joints`` in both.",
    robot=(str, Field(description="Robot id")),
    joints=(list[str], Field(description="The joint names, in the order of every q")),
    **{name: (info.annotation | None, Field(None, description=info.description))
       for name, info in MotionTaskOut.model_fields.items()},
    problems=(list[MotionOut] | None, Field(None, description="A batch: one result per "
                                            "problem, in order")),
    summary=(MotionSummary | None, Field(None, description="A batch: over its problems")),
)


# ---- running -----------------------------------------------------------------------------
_SCENES: dict[str, Any] = {}
_SCENES_KEPT = 2


def collision_scene(data: Mapping[str, Any] | None) -> Any:
    """The ``CollisionScene`` of an inline scene (keys ``SCENE_KEYS``; stored meshes must be
    filled in), None for none; ``FieldError`` at ``("scene", ...)``. The last few built are
    kept, so validating the params and running the job build it once."""
    if data is None:
        return None
    unknown = sorted(set(data) - set(SCENE_KEYS))
    if unknown:
        raise FieldError(("scene", unknown[0]), "unknown field; an inline scene has objects "
                         "and/or moveit")
    key = json.dumps(data, sort_keys=True, separators=(",", ":"))
    scene = _SCENES.get(key)
    if scene is None:
        from planning.collision import CollisionScene

        try:
            scene = CollisionScene.from_request(data, None)
        except FieldError as exc:
            raise FieldError(("scene", *exc.loc), exc.message) from None
        while len(_SCENES) >= _SCENES_KEPT:
            _SCENES.pop(next(iter(_SCENES)))
        _SCENES[key] = scene
    return scene


#: The kinds of checkers (robot model kind, with a scene, self-collision) this process has
#: run its checks on.
_WARMED: set[tuple] = set()


def warm_up(req: MotionRequest, collision_model: Any, scene: Any) -> None:
    """Before the first timed plan of a kind of checker in this process: run each check of a
    throwaway ``MotionChecker`` once (so no plan's statistics count these), so that loading
    the compiled kernels (compiling them, on a machine that never ran them: seconds) is not
    taken out of a problem's time limit."""
    key = (collision_model.kind, scene is not None and len(scene) > 0, req.self_collision)
    if key in _WARMED:
        return
    import numpy as np

    from planning.warm import warm_up as warm_kernels

    warm_kernels(["kinematics", "motion"])  # the planner's compiled kernels, once per process

    checker = req.checker(collision_model, scene)
    a = np.clip(req.start, checker.lower, checker.upper)
    b = a.copy()
    b[0] = a[0] + 0.05 if a[0] + 0.05 <= checker.upper[0] else a[0] - 0.05
    checker.free(np.stack([a, b]))
    checker.segment_free(a, b, req.resolution)
    checker.pairs(a)
    checker.clearance(np.stack([a, b]), req.resolution)
    # The exact stage's shapes (FCL's trees of the link meshes: a quarter of a second for
    # the UR5's) and the compiled stage's triangles, built once per model: here, not in the
    # first plan whose search meets a flagged state.
    from planning.collision import exact_stage
    from planning.motion.checker import TRIANGLES_MAX

    exact_stage(collision_model, scene)
    collision_model.mesh_triangles(TRIANGLES_MAX)
    _WARMED.add(key)


def motion_answer(result: Any, joint_names: list[str]) -> dict[str, Any]:
    """The fields of ``MotionOut`` of a ``MotionResult``, of ``MotionTaskOut`` of a task's
    ``TaskResult``."""
    data = result.to_dict(joint_names=joint_names)
    out = MotionTaskOut if "steps" in data else MotionOut
    return out(**pick(out, data)).model_dump(mode="json")


def summarize(results: list[dict[str, Any]]) -> dict[str, Any]:
    """``MotionSummary`` of a batch's results (``MotionOut`` dicts)."""
    solved = [r for r in results if r["status"] == MotionStatus.OK.value]
    times = [r["planning_time_s"] for r in results]
    lengths = [r["length"] for r in solved if r["length"] is not None]
    return {"solved": len(solved), "total": len(results),
            "median_planning_time_s": statistics.median(times) if times else None,
            "median_length": statistics.median(lengths) if lengths else None}


#: Problems of a batch per step of a motion job (each step builds its checker once).
MOTION_PART_PROBLEMS = 8


def motion_parts(params: MotionParams) -> list[tuple[int, int]]:
    """The job's parts: ``(first problem, end problem)``, ``MOTION_PART_PROBLEMS`` each."""
    n = 1 if params.problems is None else len(params.problems)
    return [(i, min(n, i + MOTION_PART_PROBLEMS)) for i in range(0, n, MOTION_PART_PROBLEMS)]


def motion_graph(params: MotionParams) -> list[Step]:
    """The steps of a motion job: one problem, or a batch of up to ``MOTION_PART_PROBLEMS``,
    in one step; a larger batch ``MOTION_PART_PROBLEMS`` problems per step (each problem's
    plan depends on its own seed, not on the problems planned before it with the same
    checker), and a step summing them up."""
    parts = motion_parts(params)
    if len(parts) == 1:
        return [Step(motion_whole)]
    n = parts[-1][1]
    steps = [Step(motion_part, (a, b), weight=b - a, label=f"problems {a + 1}-{b} of {n}")
             for a, b in parts]
    steps.append(Step(motion_result, ([Ref(i) for i in range(len(parts))],), weight=0.01,
                      label="summary"))
    return steps


def _plan(params: MotionParams, first: int, end: int, progress: Progress
          ) -> list[dict[str, Any]]:
    """``MotionOut`` dicts of problems ``first..end-1``, planned in turn with one checker (the
    batch's settings, the same for every problem)."""
    from planning.collision import RobotCollisionModel

    model = params.robot_model()
    if isinstance(params.scene, str):
        raise FieldError(("scene",), "a stored scene's id is filled in when the job is "
                         "submitted to the service; give the scene inline here")
    requests = params.requests(model)
    names = [j.name for j in model.joints]
    n, total = end - first, len(requests)
    progress(0.0, "building the collision model")
    imported = params.imported()
    cm = imported[1] if imported is not None else RobotCollisionModel.from_model(model)
    scene = collision_scene(params.scene)
    warm_up(requests[0], cm, scene)
    checker = requests[0].checker(cm, scene)
    results = []
    for k in range(n):
        i = first + k
        what = f"problem {i + 1} of {total}" if total > 1 else "planning"

        def report(fraction: float, *_: Any, k: int = k, what: str = what) -> None:
            progress(min(max((k + float(fraction)) / n, 0.0), 1.0) * 0.99, what)

        report(0.0)
        results.append(motion_answer(requests[i].plan(checker, model, report), names))
    return results


def motion_part(params: MotionParams, first: int, end: int, progress: Progress
                ) -> list[dict[str, Any]]:
    """Problems ``first..end-1`` of a batch: their ``MotionOut`` dicts."""
    out = _plan(params, first, end, progress)
    progress(1.0, "planned")
    return out


def motion_result(params: MotionParams, parts: list, progress: Progress) -> Any:
    """The batch's result: every part's problems, in order, and their summary."""
    results = [r for part in parts for r in part]
    progress(1.0, "done")
    return MotionJobResult(**_head(params), problems=results, summary=summarize(results))


def _head(params: MotionParams) -> dict[str, Any]:
    model = params.robot_model()
    return {"robot": model.id, "joints": [j.name for j in model.joints]}


def motion_whole(params: MotionParams, progress: Progress) -> Any:
    """One problem, or a small batch, in one step."""
    n = 1 if params.problems is None else len(params.problems)
    results = _plan(params, 0, n, progress)
    if params.problems is not None:
        return motion_result(params, [results], progress)
    progress(1.0, "done")
    return MotionJobResult(**_head(params), **results[0])


def run_motion(params: MotionParams, progress: Progress) -> Any:
    """Plan each problem with one checker per part of the batch (``motion_graph``)."""
    return run_inline(motion_graph(params), params, progress)


# ---- submission --------------------------------------------------------------------------
def _inline_meshes(objects: Any, scenes: Any, loc: list) -> Any:
    """``objects`` with each stored mesh (``"mesh": id``) replaced by its vertices and faces,
    so a worker needs no store."""
    if not isinstance(objects, list) or scenes is None:
        return objects
    out = []
    for i, o in enumerate(objects):
        if isinstance(o, dict) and o.get("type") == "mesh" and isinstance(o.get("mesh"), str):
            try:
                V, F = scenes.mesh(o["mesh"])
            except KeyError:
                raise ParamsLimitError([*loc, i, "mesh"], f"no stored mesh named "
                                       f"'{o['mesh']}'") from None
            o = {k: v for k, v in o.items() if k != "mesh"} | {
                "vertices": V.tolist(), "faces": F.tolist()}
        out.append(o)
    return out


def prepare_motion(params: dict[str, Any], submission: Submission) -> dict[str, Any]:
    """The kind's ``prepare`` hook: a submitted motion job's params, ready for a worker
    (``submission``: the service's scenes and robots): a stored scene (``"scene":
    "id"``) filled in as ``{"id", "objects"}`` and stored meshes inline.
    ``ParamsLimitError`` naming the field: 404 for an unknown scene, 413
    when the params outgrow ``MAX_MOTION_PARAMS_BYTES``, 422 for a stored mesh that is not
    there. The problems are checked against the robot once valid (``check_motion``)."""
    scenes = submission.scenes
    scene = params.get("scene")
    if isinstance(scene, str):
        try:
            stored = scenes.describe(scene) if scenes is not None else None
        except KeyError:
            stored = None
        if stored is None:
            raise ParamsLimitError(["params", "scene"], f"unknown scene '{scene}'", 404)
        scene = {"id": scene, "objects": stored["objects"]}
    if isinstance(scene, dict) and "objects" in scene:
        scene = {**scene, "objects": _inline_meshes(scene["objects"], scenes,
                                                    ["params", "scene", "objects"])}
    if scene is not params.get("scene"):
        params = {**params, "scene": scene}
        size = len(json.dumps(params, separators=(",", ":"), ensure_ascii=False).encode())
        if size > MAX_MOTION_PARAMS_BYTES:
            raise ParamsLimitError(["params", "scene"], f"the params with the scene's "
                                   f"objects take {size:,} bytes of JSON; a motion job takes "
                                   f"at most {MAX_MOTION_PARAMS_BYTES:,}", 413)
    return params


def check_motion(params: MotionParams, submission: Submission) -> None:
    """The kind's ``check`` hook: the validated params checked against the robot (joint
    counts, goal poses), ``ParamsLimitError`` (422) naming the field. An unknown robot is
    left to the manager (404)."""
    try:
        model = submission.registry.get(params.robot)
    except KeyError:
        return
    try:
        params.requests(model)
    except FieldError as exc:
        raise ParamsLimitError(["params", *exc.loc], exc.message) from None


register(JobKind("motion", MotionParams, MotionJobResult, run_motion,
                 "Joint-space motion planning in a scene (RRT-Connect / RRT*), one problem "
                 "or a batch, every path verified", needs_robot=True,
                 max_params_bytes=MAX_MOTION_PARAMS_BYTES, graph=motion_graph,
                 prepare=prepare_motion, check=check_motion, needs_geometry=True))
