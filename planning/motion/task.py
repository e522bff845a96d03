"""Tasks: a list of steps planned in order from one start, each step starting where the one
before it ended, answered as one joint path and one trajectory.

A step is one of ``STEP_TYPES``:

* ``move``: a joint-space move to a configuration or a tool pose (``plan_motion``'s search:
  RRT-Connect / RRT*, shortened), ``{"type": "move", "goal": {"q": [...]} | {"pose": 4x4},
  "planner"?, "time_limit"?, "seed"?, "simplify"?}``;
* ``line``: the tool along a straight line (``cartesian.plan_line``), ``{"type": "line",
  "target": 4x4 | [x, y, z], "orientation"?: "slerp" | "hold", "max_step"?: mm,
  "max_rotation"?: rad, "jump_threshold"?: rad, "time_limit"?}``;
* ``arc``: the tool along a circular arc (``cartesian.plan_arc``), ``{"type": "arc",
  "via": [x, y, z], "target": 4x4 | [x, y, z]}`` or ``{"type": "arc", "centre": [x, y, z],
  "axis": [x, y, z], "angle": rad}``, with ``orientation`` (``slerp``, ``hold`` or
  ``rotate``) and the line's step options.

Every step reads its fields through one row of ``STEP_TYPES`` (its name, the fields it takes,
its parser); nothing else branches on a step's type, so a new kind of step is a parser, a
class with a ``plan`` method and a row.

Planning stops at the first step that does not end ``ok``: the task's status is that step's,
and the steps done so far (the failing one included) are answered with the states they
reached. ``time_limit`` bounds the whole task: each step plans within what is left of it (a
step's own ``time_limit`` bounds it further), and a step that finds none left answers
``timeout``. The joint path of the task is the steps' states one after the other (a step's
first state is the previous step's last, kept once); when every step is ``ok`` it is timed as
one path, time-optimal within the robot's limits, like a single move's (``planner``'s
trajectory: corners blended where the blend stays free): a line's states are never
shortcut, so the tool keeps to the line.

Errors in the input are ``FieldError`` naming the step and its field (``("steps", 3,
"target")``); so is an arc whose via point lies on the line from where the tool is when the
arc starts to its target (known only once the steps before it are planned).

Example::

    >>> from planning.collision import RobotCollisionModel
    >>> from kinematics.library import builtin_model
    >>> model = builtin_model("glt_palletizer")
    >>> task = parse_task({"start": [0, 0.3, -0.3, 0, 0.5, 0], "steps": [
    ...     {"type": "move", "goal": {"q": [0.3, 0.3, -0.3, 0, 0.5, 0]}},
    ...     {"type": "line", "target": [1200, 300, 900]}]}, model)
    >>> [s.type for s in task.steps]
    ['move', 'line']
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import FieldError, Loc
from kinematics.model import MAX_LENGTH_MM

from .cartesian import (
    DEFAULT_JUMP_THRESHOLD,
    DEFAULT_LIMIT_AVOIDANCE,
    DEFAULT_MAX_ROTATION,
    DEFAULT_MAX_STEP,
    DEFAULT_ORIENTATION_TOLERANCE,
    DEFAULT_POSITION_TOLERANCE,
    ORIENTATIONS,
    CartesianStatus,
    plan_arc,
    plan_line,
)
from .cartesian import _options as _cartesian_options
from .checker import DEFAULT_RESOLUTION
from .constraints import ConstrainedStatus, parse_constraints, plan_constrained
from .planner import FINISH_S, MotionStatus, _trajectory, plan_checked, trajectory_samples
from .request import (
    MAX_TIME_LIMIT_S,
    MotionRequest,
    _flag,
    _goal,
    _joints,
    _known,
    _number,
    _planner,
    _pose,
    _seed,
    _settings,
    _time_limit,
)
from .search import path_length

if TYPE_CHECKING:
    from kinematics.model import RobotModel

    from .checker import MotionChecker

__all__ = ["MAX_TASK_STEPS", "STEP_TYPES", "StepType", "StepResult", "TaskResult",
           "TaskRequest", "TASK_STATUSES", "TASK_FIELDS", "parse_task", "parse_steps",
           "robot_task", "plan_task", "is_task"]

#: Most steps of one task (a request with more is refused, naming ``steps``).
MAX_TASK_STEPS = 100
#: Every status a task or a step may end with: a move's (``MotionStatus``), a Cartesian
#: segment's (``CartesianStatus``) and a constrained move's (``ConstrainedStatus``), in that
#: order, each once.
TASK_STATUSES = tuple(dict.fromkeys(
    [s.value for s in MotionStatus] + [s.value for s in CartesianStatus]
    + [s.value for s in ConstrainedStatus]))
#: The fields of a task body: ``start`` and ``steps`` with the shared settings of a motion
#: request (``time_limit`` bounds the whole task).
TASK_FIELDS = ("scene", "start", "steps", "planner", "time_limit", "seed", "resolution",
               "simplify", "self_collision", "margin", "trajectory")
#: The ``planner`` a task's answer names (each step names its own).
TASK_PLANNER = "task"


# ---- results -----------------------------------------------------------------------------------
@dataclass
class StepResult:
    """How one step ended. ``first``, ``last``: the indices of its first and last states in
    the task's joint path (inclusive; ``first`` is the previous step's ``last``; equal when
    the step reached nothing beyond its start). ``fraction``: the share of a line's or an
    arc's length reached (None for a move). ``planner``: what planned it (a move's search,
    ``line``, ``arc``). ``deviation``: a segment's worst distance of the tool from its ideal
    curve between two states (mm; None for a move). ``goal``: a move's goal configuration
    reached (for a goal pose, the IK branch)."""

    index: int
    type: str
    status: str
    message: str
    first: int
    last: int
    planner: str
    fraction: float | None = None
    planning_time_s: float = 0.0
    pairs: list = field(default_factory=list)
    deviation: float | None = None
    goal: np.ndarray | None = None

    @property
    def success(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"index": self.index, "type": self.type, "status": self.status,
                "message": self.message, "states": [self.first, self.last],
                "fraction": None if self.fraction is None else float(self.fraction),
                "planner": self.planner, "planning_time_s": float(self.planning_time_s),
                "pairs": [list(p) for p in self.pairs],
                "deviation": None if self.deviation is None else float(self.deviation),
                "goal": None if self.goal is None else self.goal.tolist()}


@dataclass
class TaskResult:
    """A planned task (module docstring). ``path (N, dof)``: the states of the steps done,
    ``path[0]`` the start; ``steps``: one ``StepResult`` per step planned (up to the first
    that failed). ``status`` and ``message``: ``ok``, or the failing step's (the message
    names the step). ``trajectory``: the whole path timed (None unless ``ok``, or when not
    asked); ``min_clearance`` (mm): over the whole path (None unless ``ok``); ``length``: the
    path's joint-space length (rad, mm for prismatic joints)."""

    status: str
    message: str
    path: np.ndarray
    steps: list[StepResult]
    length: float = 0.0
    planning_time_s: float = 0.0
    simplify_time_s: float = 0.0
    min_clearance: float | None = None
    trajectory: Any = None
    pairs: list = field(default_factory=list)
    resolution: float = DEFAULT_RESOLUTION
    stats: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status == "ok"

    @property
    def goal(self) -> np.ndarray | None:
        """Where the task ends (the last state) when every step succeeded, else None."""
        return self.path[-1].copy() if self.success and len(self.path) else None

    def to_dict(self, joint_names: list[str] | None = None, samples: int = 200
                ) -> dict[str, Any]:
        """JSON-ready, with the fields of a single move's answer (``MotionResult.to_dict``)
        and ``steps``; the trajectory sampled at ``samples`` equal steps."""
        goal = self.goal
        out: dict[str, Any] = {
            "status": self.status, "message": self.message, "path": self.path.tolist(),
            "length": float(self.length), "planning_time_s": float(self.planning_time_s),
            "simplify_time_s": float(self.simplify_time_s),
            "min_clearance": (None if self.min_clearance is None
                              or not math.isfinite(self.min_clearance)
                              else float(self.min_clearance)),
            "goal": None if goal is None else goal.tolist(),
            "pairs": [list(p) for p in self.pairs], "planner": TASK_PLANNER,
            "resolution": self.resolution, "stats": self.stats, "trajectory": None,
            "steps": [s.to_dict() for s in self.steps],
        }
        if joint_names is not None:
            out["joints"] = list(joint_names)
        if self.trajectory is not None:
            out["trajectory"] = trajectory_samples(self.trajectory, samples)
        return out


# ---- planning a step -----------------------------------------------------------------------------
@dataclass
class _Context:
    """What the steps of one task share while it is planned: the checker (a step that
    changes what the robot carries, ``attach``/``detach``, would replace it here), the
    kinematics, the task's settings and the deadline of its time limit."""

    checker: MotionChecker
    model: Any
    resolution: float
    deadline: float
    #: Receives the share of the current step done (a move's: of its time limit); may raise
    #: to stop the task (a cancelled job).
    report: Callable[[float], Any] | None = None

    def left(self) -> float:
        return self.deadline - time.perf_counter()


@dataclass(frozen=True)
class _Outcome:
    """A step's answer before it is placed in the task: ``states (n, dof)`` from the step's
    start (empty when it reached nothing, not even its start)."""

    status: str
    message: str
    states: np.ndarray
    planner: str
    fraction: float | None = None
    planning_time_s: float = 0.0
    simplify_time_s: float = 0.0
    pairs: tuple = ()
    deviation: float | None = None
    goal: np.ndarray | None = None


def _out_of_time(q: np.ndarray, planner: str) -> _Outcome:
    return _Outcome("timeout", "the task's time limit ran out before this step", q[None],
                    planner)


@dataclass(frozen=True)
class MoveStep:
    """A joint-space move to ``request``'s goal (its start is set when the step runs)."""

    index: int
    request: MotionRequest
    own_time_limit: float | None = None
    #: Path constraints (``constraints.parse_constraints``): the move keeps them throughout.
    constraints: tuple = ()
    type: str = "move"

    def plan(self, ctx: _Context, q: np.ndarray) -> _Outcome:
        left = ctx.left()
        if left <= 0.0:
            return _out_of_time(q, self.request.planner)
        limit = left if self.own_time_limit is None else min(left, self.own_time_limit)
        r = self.request
        if self.constraints:
            kept = plan_constrained(ctx.checker, q, r.goal, list(self.constraints),
                                    time_limit=limit, seed=r.seed, resolution=r.resolution,
                                    simplify=r.simplify, progress=ctx.report)
            states = kept.path if len(kept.path) else q[None]
            return _Outcome(kept.status.value, kept.message, states, "constrained",
                            planning_time_s=kept.planning_time_s, pairs=tuple(kept.pairs),
                            goal=r.goal if kept.success else None)
        res = plan_checked(ctx.checker, q, r.goal, r.goal_pose, model=ctx.model,
                           planner=r.planner, time_limit=limit, seed=r.seed,
                           resolution=r.resolution, simplify=r.simplify, trajectory=False,
                           progress=ctx.report)
        states = res.path if len(res.path) else q[None]
        return _Outcome(res.status.value, res.message, states, res.planner or r.planner,
                        planning_time_s=res.planning_time_s,
                        simplify_time_s=res.simplify_time_s, pairs=tuple(res.pairs),
                        goal=res.goal if res.success else None)


@dataclass(frozen=True)
class SegmentStep:
    """A Cartesian segment: ``plan_line`` or ``plan_arc`` with ``args`` (checked)."""

    index: int
    type: str
    args: Mapping[str, Any]
    own_time_limit: float | None = None

    def plan(self, ctx: _Context, q: np.ndarray) -> _Outcome:
        left = ctx.left()
        if left <= 0.0:
            return _out_of_time(q, self.type)
        limit = left if self.own_time_limit is None else min(left, self.own_time_limit)
        follow = plan_line if self.type == "line" else plan_arc
        with _at(("steps", self.index)):
            res = follow(ctx.checker, q, **self.args, resolution=ctx.resolution,
                         time_limit=limit, model=ctx.model)
        states = res.path if len(res.path) else q[None]
        return _Outcome(res.status.value, res.message, np.array(states), self.type,
                        fraction=res.fraction, planning_time_s=res.planning_time_s,
                        pairs=tuple(res.pairs), deviation=res.deviation)


def _rechecked(checker: MotionChecker, collision_model: Any, scene: Any) -> MotionChecker:
    """``checker`` with another collision model or scene, its settings kept."""
    from .checker import MotionChecker

    fresh = MotionChecker(collision_model, scene, lower=checker.lower, upper=checker.upper,
                          self_collision=checker.self_collision, margin=checker.margin)
    fresh.deadline = checker.deadline
    return fresh


def _held(ctx: _Context, q: np.ndarray, planner: str, message: str, t0: float) -> _Outcome:
    """The answer of a step that changes what the robot carries: ``ok`` if the robot, with
    what it carries now, is free where it stands, else ``collision`` with the pairs."""
    if bool(ctx.checker.free(q)):
        return _Outcome("ok", message, q[None], planner,
                        planning_time_s=time.perf_counter() - t0)
    pairs = tuple(ctx.checker.pairs(q))
    return _Outcome("collision", f"{message}, but then it collides: "
                    + ", ".join(f"{a}-{b}" for a, b in pairs), q[None], planner,
                    planning_time_s=time.perf_counter() - t0, pairs=pairs)


@dataclass(frozen=True)
class AttachStep:
    """The robot takes ``attachment`` (``planning.collision.Attachment``): from this step
    on it moves with its link and is checked like a link."""

    index: int
    attachment: Any
    type: str = "attach"

    def carried(self, before: frozenset, loc: Loc) -> frozenset:
        if self.attachment.id in before:
            raise FieldError((*loc, "object", "id"), f"'{self.attachment.id}' is carried "
                             "already")
        return before | {self.attachment.id}

    def plan(self, ctx: _Context, q: np.ndarray) -> _Outcome:
        t0 = time.perf_counter()
        try:
            model = ctx.checker.cm.with_attached([self.attachment])
        except FieldError as exc:  # a link the robot does not have: named from the step
            raise FieldError(("steps", self.index, *_step_field(exc.loc)), exc.message) \
                from None
        ctx.checker = _rechecked(ctx.checker, model, ctx.checker.scene)
        a = self.attachment
        return _held(ctx, q, "attach", f"carrying '{a.id}' on {a.link}", t0)


@dataclass(frozen=True)
class DetachStep:
    """The robot lets go of the object ``object_id``; with ``place`` it stays where it is,
    one more object of the scene for the steps after."""

    index: int
    object_id: str
    place: bool = True
    type: str = "detach"

    def carried(self, before: frozenset, loc: Loc) -> frozenset:
        if self.object_id not in before:
            carried = ", ".join(sorted(before)) or "nothing"
            raise FieldError((*loc, "object"), f"'{self.object_id}' is not carried here "
                             f"(an earlier attach step takes it; carried: {carried})")
        return before - {self.object_id}

    def plan(self, ctx: _Context, q: np.ndarray) -> _Outcome:
        t0 = time.perf_counter()
        cm = ctx.checker.cm
        scene = ctx.checker.scene
        if self.place:
            from planning.collision import CollisionScene

            pose = cm.state_frames(q[None])[0, list(cm.names).index(self.object_id)]
            (held,) = [a for a in cm.attached if a.id == self.object_id]
            placed = {**held.object.to_dict(), "pose": pose.tolist()}
            objects = [] if scene is None else scene.to_dicts()
            scene = CollisionScene.from_request({"objects": [*objects, placed]})
        kept = [a for a in cm.attached if a.id != self.object_id]
        base = cm.without_attached()
        model = base.with_attached(kept) if kept else base
        ctx.checker = _rechecked(ctx.checker, model, scene)
        where = "placed where it is" if self.place else "dropped from the task"
        return _held(ctx, q, "detach", f"let go of '{self.object_id}' ({where})", t0)


# ---- parsing a step ------------------------------------------------------------------------------
@contextlib.contextmanager
def _at(loc: Loc) -> Iterator[None]:
    """``FieldError``s raised inside, named relative to ``loc`` (a step's)."""
    try:
        yield
    except FieldError as exc:
        raise FieldError((*loc, *exc.loc), exc.message) from None


def _own_time_limit(item: Mapping[str, Any], loc: Loc, most: float) -> float | None:
    v = item.get("time_limit")
    return None if v is None else _time_limit(v, (*loc, "time_limit"), most)


def _parse_move(item: Mapping[str, Any], index: int, model: RobotModel, start: np.ndarray,
                settings: Mapping[str, Any], loc: Loc) -> MoveStep:
    if item.get("goal") is None:
        raise FieldError((*loc, "goal"), "required: {\"q\": [joint values]} or {\"pose\": "
                                         "4x4 tool pose}")
    q_goal, goal_pose = _goal(item["goal"], model, (*loc, "goal"))
    own = {k: settings[k] for k in ("planner", "seed", "resolution", "simplify",
                                    "self_collision", "margin")}
    if item.get("planner") is not None:
        own["planner"] = _planner(item["planner"], (*loc, "planner"))
    if item.get("seed") is not None:
        own["seed"] = _seed(item["seed"], (*loc, "seed"))
    if item.get("simplify") is not None:
        own["simplify"] = _flag(item["simplify"], (*loc, "simplify"))
    constraints: tuple = ()
    if item.get("constraints") is not None:
        constraints = parse_constraints(item["constraints"], model, loc=(*loc, "constraints"))
        if goal_pose is not None:
            raise FieldError((*loc, "goal"), "a constrained move needs its goal as joint "
                                             "values: {\"q\": [...]}")
    req = MotionRequest(start=start, goal=q_goal, goal_pose=goal_pose, trajectory=False,
                        time_limit=settings["time_limit"], **own)
    return MoveStep(index, req, _own_time_limit(item, loc, settings["time_limit"]),
                    constraints=constraints)


def _point_or_pose(v: Any, loc: Loc) -> np.ndarray:
    """A target: a 4x4 pose (rigid within the motion request's tolerance, projected onto the
    nearest rigid pose) or a point ``[x, y, z]`` (mm)."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if isinstance(v, Sequence) and not isinstance(v, str | bytes) and len(v) == 4:
        return _pose(v, loc)
    return _point(v, loc)


def _point(v: Any, loc: Loc, what: str = "a point [x, y, z] (mm)") -> np.ndarray:
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, Sequence) or isinstance(v, str | bytes) or len(v) != 3:
        raise FieldError(loc, f"must be {what}" + (" or a 4x4 pose" if "point" in what
                                                   and loc[-1] == "target" else ""))
    p = np.array([_number(x, (*loc, k), f"[{k}]") for k, x in enumerate(v)])
    if np.abs(p).max() > MAX_LENGTH_MM:
        raise FieldError(loc, f"every entry must be within ±{MAX_LENGTH_MM:g} mm")
    return p


def _segment_options(item: Mapping[str, Any], loc: Loc, orientations: tuple[str, ...]
                     ) -> dict[str, Any]:
    """The step options of a line or an arc, checked as ``plan_line`` checks them."""
    args: dict[str, Any] = {}
    o = item.get("orientation", "slerp")
    if o not in orientations:
        raise FieldError((*loc, "orientation"), f"orientation must be one of "
                                                f"{', '.join(orientations)}")
    args["orientation"] = str(o)
    for key, default in (("max_step", DEFAULT_MAX_STEP),
                         ("max_rotation", DEFAULT_MAX_ROTATION),
                         ("jump_threshold", DEFAULT_JUMP_THRESHOLD)):
        args[key] = item.get(key, default)
    with _at(loc):
        _cartesian_options(args["max_step"], args["max_rotation"], args["jump_threshold"],
                           DEFAULT_POSITION_TOLERANCE, DEFAULT_ORIENTATION_TOLERANCE,
                           DEFAULT_RESOLUTION, DEFAULT_LIMIT_AVOIDANCE)
    for key in ("max_step", "max_rotation", "jump_threshold"):
        args[key] = float(args[key])
    return args


def _parse_line(item: Mapping[str, Any], index: int, model: RobotModel, start: np.ndarray,
                settings: Mapping[str, Any], loc: Loc) -> SegmentStep:
    if item.get("target") is None:
        raise FieldError((*loc, "target"), "required: a 4x4 pose or a point [x, y, z] (mm)")
    args = {"target": _point_or_pose(item["target"], (*loc, "target"))}
    args |= _segment_options(item, loc, ORIENTATIONS[:2])
    return SegmentStep(index, "line", args,
                       _own_time_limit(item, loc, settings["time_limit"]))


def _parse_arc(item: Mapping[str, Any], index: int, model: RobotModel, start: np.ndarray,
               settings: Mapping[str, Any], loc: Loc) -> SegmentStep:
    args: dict[str, Any] = {}
    if item.get("via") is not None:
        for key in ("centre", "axis", "angle"):
            if item.get(key) is not None:
                raise FieldError((*loc, key), "give via and target, or centre, axis and "
                                              "angle, not both")
        if item.get("target") is None:
            raise FieldError((*loc, "target"), "required with via: a 4x4 pose or a point")
        args["via"] = _point(item["via"], (*loc, "via"))
        args["target"] = _point_or_pose(item["target"], (*loc, "target"))
    else:
        for key in ("centre", "axis", "angle"):
            if item.get(key) is None:
                raise FieldError((*loc, key), "required: give via and target, or centre, "
                                              "axis and angle")
        if item.get("target") is not None:
            raise FieldError((*loc, "target"), "an arc about a centre ends where its angle "
                                               "does: leave target out")
        args["centre"] = _point(item["centre"], (*loc, "centre"))
        axis = _point(item["axis"], (*loc, "axis"), "a direction [x, y, z]")
        if np.linalg.norm(axis) < 1e-9:
            raise FieldError((*loc, "axis"), "axis must be a non-zero vector")
        args["axis"] = axis
        angle = _number(item["angle"], (*loc, "angle"), "angle")
        if abs(angle) > 2 * math.pi:
            raise FieldError((*loc, "angle"), "angle must be within [-2 pi, 2 pi] (rad)")
        args["angle"] = angle
    args |= _segment_options(item, loc, ORIENTATIONS)
    return SegmentStep(index, "arc", args, _own_time_limit(item, loc, settings["time_limit"]))


def _step_field(loc: Loc) -> Loc:
    """An attachment's error location from the step: ``("attached", i, field)`` -> field."""
    return tuple(loc[2:]) if tuple(loc[:1]) == ("attached",) else tuple(loc)


def _parse_attach(item: Mapping[str, Any], index: int, model: RobotModel, start: np.ndarray,
                  settings: Mapping[str, Any], loc: Loc) -> AttachStep:
    from planning.collision import Attachment

    if item.get("object") is None:
        raise FieldError((*loc, "object"), "required: the object to carry (a box, sphere, "
                                           "cylinder, capsule or mesh, as in a scene)")
    data = {k: item[k] for k in ("object", "link", "pose", "touch_links") if k in item}
    try:
        attachment = Attachment.from_dict(data, index)
    except FieldError as exc:
        raise FieldError((*loc, *_step_field(exc.loc)), exc.message) from None
    return AttachStep(index, attachment)


def _parse_detach(item: Mapping[str, Any], index: int, model: RobotModel, start: np.ndarray,
                  settings: Mapping[str, Any], loc: Loc) -> DetachStep:
    oid = item.get("object")
    if not isinstance(oid, str) or not oid:
        raise FieldError((*loc, "object"), "required: the id of an object an earlier attach "
                                           "step took")
    return DetachStep(index, oid, _flag(item.get("place", True), (*loc, "place")))


@dataclass(frozen=True)
class StepType:
    """One kind of step: its ``name`` (the step's ``type``), the ``fields`` it takes besides
    ``type`` (any other is refused, named), and ``parse(item, index, model, start, settings,
    loc)``, which checks the step (``FieldError`` at ``loc`` + its field) and answers an
    object with ``type`` and ``plan(context, q_start) -> outcome``."""

    name: str
    fields: tuple[str, ...]
    parse: Callable[..., Any]


_SEGMENT_OPTIONS = ("orientation", "max_step", "max_rotation", "jump_threshold", "time_limit")

#: The kinds of step, by ``type``. ``attach`` and ``detach`` change what the robot carries
#: from there on (they replace the context's checker).
STEP_TYPES: dict[str, StepType] = {t.name: t for t in (
    StepType("move", ("goal", "planner", "time_limit", "seed", "simplify", "constraints"),
             _parse_move),
    StepType("line", ("target", *_SEGMENT_OPTIONS), _parse_line),
    StepType("arc", ("target", "via", "centre", "axis", "angle", *_SEGMENT_OPTIONS),
             _parse_arc),
    StepType("attach", ("object", "link", "pose", "touch_links"), _parse_attach),
    StepType("detach", ("object", "place"), _parse_detach),
)}


def _parse_step(item: Any, index: int, model: RobotModel, start: np.ndarray,
                settings: Mapping[str, Any], loc: Loc) -> Any:
    if not isinstance(item, Mapping):
        raise FieldError(loc, "must be an object with a type: " + ", ".join(STEP_TYPES))
    if item.get("type") is None:
        raise FieldError((*loc, "type"), f"required: one of {', '.join(STEP_TYPES)}")
    kind = STEP_TYPES.get(item["type"]) if isinstance(item["type"], str) else None
    if kind is None:
        raise FieldError((*loc, "type"), f"unknown step type {item.get('type')!r}; one of "
                                         f"{', '.join(STEP_TYPES)}")
    _known(item, ("type", *kind.fields), loc)
    return kind.parse(item, index, model, start, settings, loc)


# ---- requests ------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TaskRequest:
    """A checked task: ``plan(checker)`` runs it. ``start (dof,)``; ``steps``: the parsed
    steps; the settings of a motion request (``time_limit``: the whole task's)."""

    start: np.ndarray
    steps: tuple
    scene: str | dict | None = None
    time_limit: float = 5.0
    resolution: float = DEFAULT_RESOLUTION
    self_collision: bool = True
    margin: float = 0.0
    trajectory: bool = True

    def checker(self, collision_model: Any, scene: Any = None) -> Any:
        """The ``MotionChecker`` of the task's robot in ``scene`` (``MotionRequest.checker``)."""
        from .checker import MotionChecker

        return MotionChecker(collision_model, scene, self_collision=self.self_collision,
                             margin=self.margin)

    def plan(self, checker: Any, model: RobotModel | None = None, progress: Any = None
             ) -> TaskResult:
        """``plan_task`` of this request's steps with ``checker``."""
        return _plan(checker, self.start, self.steps, model=model,
                     time_limit=self.time_limit, resolution=self.resolution,
                     trajectory=self.trajectory, progress=progress)


def is_task(body: Mapping[str, Any]) -> bool:
    """Whether ``body`` asks for a task (``steps``) rather than one move."""
    return isinstance(body, Mapping) and body.get("steps") is not None


def parse_steps(items: Any, model: RobotModel, start: np.ndarray,
                settings: Mapping[str, Any], *, loc: Loc = ("steps",),
                max_steps: int = MAX_TASK_STEPS) -> tuple:
    """The steps of a task, each checked (``STEP_TYPES``) with the task's ``settings``
    (``planner``, ``seed``, ``resolution``, ``simplify``, ``self_collision``, ``margin``,
    ``time_limit``: the defaults of its steps); ``FieldError`` at ``loc`` + index + field."""
    if not isinstance(items, Sequence) or isinstance(items, str | bytes):
        raise FieldError(loc, "must be a list of steps ({\"type\": \"move\" | \"line\" | "
                              "\"arc\", ...})")
    if not 1 <= len(items) <= max_steps:
        raise FieldError(loc, f"give 1 to {max_steps} steps, got {len(items)}")
    steps = tuple(_parse_step(item, i, model, start, settings, (*loc, i))
                  for i, item in enumerate(items))
    carried: frozenset = frozenset()
    for i, step in enumerate(steps):  # what each step carries: attach before detach
        change = getattr(step, "carried", None)
        if change is not None:
            carried = change(carried, (*loc, i))
    return steps


def robot_task(model: RobotModel, start: Any, steps: Any, *, loc: Loc = (),
               **settings: Any) -> TaskRequest:
    """A task of ``model`` whose settings (``planner``, ``time_limit``, ``seed``,
    ``resolution``, ``simplify``, ``self_collision``, ``margin``, ``trajectory``, ``scene``)
    are checked already (the service's pydantic models): ``start`` and every step are checked
    here (``FieldError`` at ``loc`` + the field)."""
    q_start = _joints(start, model, (*loc, "start"))
    parsed = parse_steps(steps, model, q_start, settings, loc=(*loc, "steps"))
    return TaskRequest(start=q_start, steps=parsed, scene=settings.get("scene"),
                       time_limit=float(settings["time_limit"]),
                       resolution=float(settings["resolution"]),
                       self_collision=bool(settings["self_collision"]),
                       margin=float(settings["margin"]),
                       trajectory=bool(settings["trajectory"]))


def parse_task(body: Mapping[str, Any], model: RobotModel, *,
               max_time_limit: float = MAX_TIME_LIMIT_S,
               ignore: Collection[str] = ()) -> TaskRequest:
    """A task of ``model`` from a JSON body (``TASK_FIELDS``; keys in ``ignore`` skipped, a
    key set to None absent), checked as ``parse_motion_request`` checks a move;
    ``FieldError`` naming the field (``("steps", 2, "target")``)."""
    if not isinstance(body, Mapping):
        raise FieldError((), "a motion request must be a JSON object")
    body = {k: v for k, v in body.items() if k not in ignore and v is not None}
    if "goal" in body:
        raise FieldError(("goal",), "give goal (one move) or steps (a task), not both")
    _known(body, TASK_FIELDS, ())
    for key in ("start", "steps"):
        if key not in body:
            raise FieldError((key,), "required")
    settings = _settings(body, max_time_limit)
    return robot_task(model, body["start"], body["steps"], **settings)


# ---- planning ------------------------------------------------------------------------------------
def plan_task(checker: MotionChecker, start: Any, steps: Any, *, model: Any = None,
              time_limit: float = 5.0, resolution: float = DEFAULT_RESOLUTION,
              planner: str = "auto", seed: int = 0, simplify: bool = True,
              trajectory: bool = True, limits: Any = None, hydraulics: Any = None,
              progress: Any = None) -> TaskResult:
    """Plan ``steps`` (JSON-like dicts, ``STEP_TYPES``) in order from ``start`` with
    ``checker`` (module docstring). ``time_limit`` (s) bounds the whole task; ``planner``,
    ``seed`` and ``simplify`` are the moves' defaults; ``limits`` and ``hydraulics`` time the
    trajectory (default: the model's, as ``plan_motion``'s). ``progress`` receives the share
    of the steps done. ``FieldError`` naming the step and its field for bad input."""
    model = checker.robot_model if model is None else model
    settings = {"planner": _planner(planner, ("planner",)), "seed": _seed(seed, ("seed",)),
                "resolution": float(resolution), "simplify": _flag(simplify, ("simplify",)),
                "self_collision": checker.self_collision, "margin": checker.margin,
                "time_limit": _time_limit(time_limit, ("time_limit",), 3600.0)}
    q_start = _joints(start, model, ("start",))
    parsed = parse_steps(steps, model, q_start, settings)
    return _plan(checker, q_start, parsed, model=model, time_limit=settings["time_limit"],
                 resolution=float(resolution), trajectory=trajectory, limits=limits,
                 hydraulics=hydraulics, progress=progress)


def _plan(checker: MotionChecker, q_start: np.ndarray, steps: Sequence[Any], *, model: Any,
          time_limit: float, resolution: float, trajectory: bool, limits: Any = None,
          hydraulics: Any = None, progress: Any = None) -> TaskResult:
    t0 = time.perf_counter()
    model = checker.robot_model if model is None else model
    ctx = _Context(checker, model, resolution, t0 + time_limit)
    q = np.asarray(q_start, dtype=float)
    chunks = [q[None]]
    count = 1                     # states in the path so far
    done: list[StepResult] = []
    simplify_time = 0.0
    status, message, pairs = "ok", "ok", []
    n = len(steps)
    for i, step in enumerate(steps):
        if progress is not None:
            progress(i / n)
            ctx.report = lambda f, i=i: progress((i + min(max(float(f), 0.0), 1.0)) / n)
        out = step.plan(ctx, q)
        new = out.states[1:] if len(out.states) else out.states
        first = count - 1
        chunks.append(new)
        count += len(new)
        simplify_time += out.simplify_time_s
        done.append(StepResult(i, step.type, out.status, out.message, first, count - 1,
                               out.planner, out.fraction, out.planning_time_s,
                               list(out.pairs), out.deviation, out.goal))
        if out.status != "ok":
            status, pairs = out.status, list(out.pairs)
            message = f"step {i} ({step.type}): {out.message}"
            break
        q = out.states[-1]
    path = np.concatenate(chunks)
    result = TaskResult(status, message, path, done, length=path_length(path),
                        simplify_time_s=simplify_time, pairs=pairs, resolution=resolution,
                        stats={"steps": len(steps), "steps_planned": len(done),
                               "states": len(path)})
    if status == "ok":
        saved = checker.deadline
        if trajectory and len(path) > 1:
            # The timing's modules loaded first (seconds on a first call), so that the
            # blend checks' deadline is theirs: a line's states kept with sharp corners
            # would stop the arm at every state.
            import planning.trajectories.hydraulic  # noqa: F401
            import planning.trajectories.joint_path  # noqa: F401
            import planning.trajectories.topp  # noqa: F401

            checker.deadline = time.perf_counter() + FINISH_S
            try:
                result.trajectory, note = _trajectory(checker, path, resolution, limits,
                                                      hydraulics)
            except FieldError as exc:     # a path that does not move: nothing to time
                note = f"not timed: {exc.message}"
            finally:
                checker.deadline = saved
            if note:
                result.stats["trajectory"] = note
        result.min_clearance = checker.clearance(path, resolution)
    result.planning_time_s = time.perf_counter() - t0
    if progress is not None:
        progress(1.0)
    return result
