"""Motion requests: a JSON body (the REST API's, a job's, one read from a file) checked
against a robot and turned into the arguments of ``plan_motion``.

One problem::

    {"scene": ..., "start": [q], "goal": {"q": [q]} | {"pose": T_world_tool (4x4, mm)},
     "planner": "auto", "time_limit": 5, "seed": 0, "resolution": 0.01, "simplify": true,
     "self_collision": true, "margin": 0, "trajectory": true}

or many problems sharing the robot, the scene and the settings: ``"problems": [{"start",
"goal", "seed"?, "time_limit"?}, ...]`` in place of ``start`` and ``goal``.

Joint values are in the robot model's joint order (rad; mm for prismatic joints). Every
error is a ``kinematics.errors.FieldError`` whose ``loc`` names the field relative to the
body (``("start",)``, ``("goal", "pose")``, ``("problems", 3, "goal", "q")``), so the
service answers 422 there before any planning starts. ``scene`` is passed through as given
(a stored scene's id, an inline scene or None): finding a stored scene is the caller's
business.

A caller whose body is typed and checked already (the service's pydantic models: field
types, bounds, unknown fields) builds its problems with ``robot_problem``, which checks only
what depends on the robot, with the same messages and locations: a body is validated once.

Example::

    >>> from kinematics.library import builtin_model
    >>> model = builtin_model("glt_palletizer")
    >>> req = parse_motion_request({"start": [0] * 6, "goal": {"q": [0.5] + [0] * 5}}, model)
    >>> req.goal.tolist(), req.planner, req.time_limit
    ([0.5, 0.0, 0.0, 0.0, 0.0, 0.0], 'auto', 5.0)
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from kinematics.errors import FieldError, Loc
from kinematics.model import MAX_LENGTH_MM
from kinematics.transforms import project_to_rigid, rigidity_error

from .checker import DEFAULT_RESOLUTION, PRISMATIC_STEP
from .planner import MAX_RESOLUTION, MIN_RESOLUTION, PLANNERS

if TYPE_CHECKING:
    from kinematics.model import RobotModel

__all__ = [
    "MotionRequest",
    "parse_motion_request",
    "parse_motion_problems",
    "robot_problem",
    "is_batch",
    "REQUEST_FIELDS",
    "PROBLEM_FIELDS",
    "DEFAULT_TIME_LIMIT_S",
    "MAX_TIME_LIMIT_S",
    "MAX_RESOLUTION",
    "MIN_RESOLUTION",
    "MAX_MARGIN_MM",
    "MAX_SEED",
    "MAX_PROBLEMS",
    "MAX_JOINT_VALUE",
    "POSE_RIGIDITY_TOL",
]

#: Seconds one problem may plan unless the request says otherwise (``plan_motion``'s).
DEFAULT_TIME_LIMIT_S = 5.0
#: Longest ``time_limit`` (s) of one problem.
MAX_TIME_LIMIT_S = 60.0
#: Largest ``margin`` (mm).
MAX_MARGIN_MM = 100_000.0
#: Largest seed (a 32-bit generator seed).
MAX_SEED = 2**32 - 1
#: Most problems in one request.
MAX_PROBLEMS = 1_000
#: Largest |joint value| (rad or mm): the longest prismatic stroke a model may have.
MAX_JOINT_VALUE = MAX_LENGTH_MM
#: Largest departure from a rigid transform of a goal pose (``rigidity_error``); the pose
#: is then projected onto the nearest rigid one. Matrices printed to four decimals pass.
POSE_RIGIDITY_TOL = 2e-3

#: The fields of a one-problem body.
REQUEST_FIELDS = ("scene", "start", "goal", "planner", "time_limit", "seed", "resolution",
                  "simplify", "self_collision", "margin", "trajectory")
#: The fields of one item of ``problems`` (the rest are shared by every problem).
PROBLEM_FIELDS = ("start", "goal", "seed", "time_limit")
_SHARED_FIELDS = tuple(f for f in REQUEST_FIELDS if f not in ("start", "goal"))


@dataclass(frozen=True, eq=False)
class MotionRequest:
    """One checked problem: ``plan(checker)`` runs it.

    ``start (dof,)`` and ``goal (dof,)`` joint values in the model's order; or, instead of
    ``goal``, ``goal_pose (4, 4)`` the tool pose ``T_world_tool`` (mm, rigid). ``scene`` is
    the body's ``scene`` as given (an id, an inline scene dict, or None)."""

    start: np.ndarray
    goal: np.ndarray | None
    goal_pose: np.ndarray | None
    scene: str | dict | None = None
    planner: str = "auto"
    time_limit: float = DEFAULT_TIME_LIMIT_S
    seed: int = 0
    resolution: float = DEFAULT_RESOLUTION
    simplify: bool = True
    self_collision: bool = True
    margin: float = 0.0
    trajectory: bool = True

    def checker(self, collision_model: Any, scene: Any = None) -> Any:
        """The ``MotionChecker`` of this request's robot (``collision_model``) in ``scene``
        (a ``CollisionScene`` or None), with its ``self_collision`` and ``margin``."""
        from .checker import MotionChecker

        return MotionChecker(collision_model, scene, self_collision=self.self_collision,
                             margin=self.margin)

    def plan(self, checker: Any, model: RobotModel | None = None, progress: Any = None
             ) -> Any:
        """``plan_motion`` of this request with ``checker`` (see ``checker``); ``model`` is
        the robot model (IK of a goal pose, default trajectory limits). The request was
        checked when it was read: its values go to the planner as they are
        (``plan_checked``), not through ``plan_motion``'s checks again."""
        from .planner import plan_checked

        return plan_checked(
            checker, np.asarray(self.start, dtype=float),
            None if self.goal is None else np.asarray(self.goal, dtype=float),
            None if self.goal_pose is None else np.asarray(self.goal_pose, dtype=float),
            model=model, planner=self.planner, time_limit=float(self.time_limit),
            seed=int(self.seed), resolution=float(self.resolution), simplify=self.simplify,
            trajectory=self.trajectory, progress=progress)


# ---- fields ---------------------------------------------------------------------------------
def _is_number(v: Any) -> bool:
    return isinstance(v, int | float | np.integer | np.floating) and not isinstance(v, bool)


def _number(v: Any, loc: Loc, what: str) -> float:
    if not _is_number(v):
        raise FieldError(loc, f"{what} must be a number, got {type(v).__name__}")
    x = float(v)
    if not math.isfinite(x):
        raise FieldError(loc, f"{what} must be a finite number, got {x}")
    return x


def _flag(v: Any, loc: Loc) -> bool:
    if not isinstance(v, bool | np.bool_):
        raise FieldError(loc, f"must be true or false, got {type(v).__name__}")
    return bool(v)


def _joints(v: Any, model: RobotModel, loc: Loc) -> np.ndarray:
    """A configuration of ``model``: ``dof`` finite numbers within ±MAX_JOINT_VALUE."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not isinstance(v, Sequence) or isinstance(v, str | bytes):
        raise FieldError(loc, f"must be a list of {model.dof} joint values (rad or mm)")
    if len(v) != model.dof:
        names = ", ".join(j.name for j in model.joints)
        raise FieldError(loc, f"expected {model.dof} joint values for robot '{model.id}' "
                              f"({names}), got {len(v)}")
    q = np.empty(model.dof)
    for k, x in enumerate(v):
        q[k] = _number(x, (*loc, k), f"joint '{model.joints[k].name}'")
        if abs(q[k]) > MAX_JOINT_VALUE:
            raise FieldError((*loc, k), f"joint '{model.joints[k].name}' must be within "
                                        f"±{MAX_JOINT_VALUE:g}")
    return q


def _pose(v: Any, loc: Loc) -> np.ndarray:
    """A rigid 4x4 pose (mm), projected onto the nearest rigid one."""
    if isinstance(v, np.ndarray):
        v = v.tolist()
    if not (isinstance(v, Sequence) and len(v) == 4 and all(
            isinstance(r, Sequence) and not isinstance(r, str) and len(r) == 4 for r in v)):
        raise FieldError(loc, "must be a 4x4 matrix (a list of 4 rows of 4 numbers)")
    T = np.empty((4, 4))
    for i, row in enumerate(v):
        for j, x in enumerate(row):
            T[i, j] = _number(x, loc, f"pose[{i}][{j}]")
    if np.abs(T).max() > MAX_LENGTH_MM:
        raise FieldError(loc, f"every entry must be within ±{MAX_LENGTH_MM:g} mm")
    err = float(rigidity_error(T))
    if err > POSE_RIGIDITY_TOL:
        raise FieldError(loc, "is not a rigid transform: its rotation part is not orthonormal "
                              "with determinant 1 or its last row is not [0, 0, 0, 1] "
                              f"(error {err:.3g})")
    return project_to_rigid(T)


def _goal(v: Any, model: RobotModel, loc: Loc) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(goal q, goal pose)`` of ``{"q": [...]}`` or ``{"pose": 4x4}``."""
    if not isinstance(v, Mapping):
        raise FieldError(loc, 'must be {"q": [joint values]} or {"pose": 4x4 tool pose}')
    for key in v:
        if key not in ("q", "pose"):
            raise FieldError((*loc, key), "unknown field; a goal is {\"q\": [...]} or "
                                          "{\"pose\": [[...]]}")
    has_q, has_pose = v.get("q") is not None, v.get("pose") is not None
    if has_q == has_pose:
        raise FieldError(loc, 'give exactly one of "q" (joint values) and "pose" (the tool '
                              "pose, 4x4 mm)")
    if has_q:
        return _joints(v["q"], model, (*loc, "q")), None
    return None, _pose(v["pose"], (*loc, "pose"))


def _seed(v: Any, loc: Loc) -> int:
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or not 0 <= v <= MAX_SEED:
        raise FieldError(loc, f"must be an integer 0..{MAX_SEED}")
    return int(v)


def _time_limit(v: Any, loc: Loc, most: float) -> float:
    t = _number(v, loc, "time_limit")
    if not 0.0 < t <= most:
        raise FieldError(loc, f"time_limit must be > 0 and at most {most:g} s, got {t:g}")
    return t


def _planner(v: Any, loc: Loc) -> str:
    if v not in PLANNERS:
        raise FieldError(loc, f"unknown planner {v!r}; one of {', '.join(PLANNERS)}")
    return str(v)


def _resolution(v: Any, loc: Loc) -> float:
    r = _number(v, loc, "resolution")
    if not MIN_RESOLUTION <= r <= MAX_RESOLUTION:
        raise FieldError(loc, f"resolution must be within {MIN_RESOLUTION:g}..{MAX_RESOLUTION:g}"
                              f" rad (x {PRISMATIC_STEP:g} mm on prismatic joints), got {r:g}")
    return r


def _margin(v: Any, loc: Loc) -> float:
    m = _number(v, loc, "margin")
    if not 0.0 <= m <= MAX_MARGIN_MM:
        raise FieldError(loc, f"margin must be within 0..{MAX_MARGIN_MM:g} mm, got {m:g}")
    return m


def _scene(v: Any, loc: Loc) -> str | dict | None:
    if v is None or isinstance(v, str | Mapping):
        return v if not isinstance(v, Mapping) else dict(v)
    raise FieldError(loc, "must be a stored scene's id, an inline scene ({\"objects\": "
                          "[...]} and/or {\"moveit\": {...}}) or null")


def _known(body: Mapping[str, Any], fields: Collection[str], loc: Loc) -> None:
    for key in body:
        if key not in fields:
            raise FieldError((*loc, key), f"unknown field; known: {', '.join(fields)}")


def _settings(body: Mapping[str, Any], max_time_limit: float) -> dict[str, Any]:
    """The shared settings of a body, checked, defaults filled in."""
    out: dict[str, Any] = {}
    get = body.get
    out["scene"] = _scene(get("scene"), ("scene",))
    out["planner"] = _planner(get("planner", "auto"), ("planner",))
    out["time_limit"] = _time_limit(get("time_limit", min(DEFAULT_TIME_LIMIT_S,
                                                          max_time_limit)),
                                    ("time_limit",), max_time_limit)
    out["seed"] = _seed(get("seed", 0), ("seed",))
    out["resolution"] = _resolution(get("resolution", DEFAULT_RESOLUTION), ("resolution",))
    for key in ("simplify", "self_collision", "trajectory"):
        out[key] = _flag(get(key, True), (key,))
    out["margin"] = _margin(get("margin", 0.0), ("margin",))
    return out


def robot_problem(model: RobotModel, start: Any, goal: Mapping[str, Any], *, loc: Loc = (),
                  **settings: Any) -> MotionRequest:
    """One problem of ``model`` whose settings (``planner``, ``time_limit``, ``seed``,
    ``resolution``, ``simplify``, ``self_collision``, ``margin``, ``trajectory``, ``scene``:
    the ``MotionRequest`` fields besides the endpoints) are already checked, as a typed
    model (the service's pydantic models) or ``parse_motion_request`` checks them: only what
    depends on the robot is checked here, ``start (dof,)`` and ``goal`` (``{"q": (dof,)}``
    or ``{"pose": (4, 4)}``, mm, projected onto the nearest rigid pose). ``FieldError`` at
    ``loc`` + the field."""
    q_start = _joints(start, model, (*loc, "start"))
    q_goal, goal_pose = _goal(goal, model, (*loc, "goal"))
    return MotionRequest(start=q_start, goal=q_goal, goal_pose=goal_pose, **settings)


def _problem(item: Any, model: RobotModel, settings: dict[str, Any], loc: Loc,
             max_time_limit: float) -> MotionRequest:
    if not isinstance(item, Mapping):
        raise FieldError(loc, "must be an object with start and goal")
    _known(item, PROBLEM_FIELDS, loc)
    for key in ("start", "goal"):
        if item.get(key) is None:
            raise FieldError((*loc, key), "required")
    start = _joints(item["start"], model, (*loc, "start"))
    goal, goal_pose = _goal(item["goal"], model, (*loc, "goal"))
    own = dict(settings)
    if item.get("seed") is not None:
        own["seed"] = _seed(item["seed"], (*loc, "seed"))
    if item.get("time_limit") is not None:
        own["time_limit"] = _time_limit(item["time_limit"], (*loc, "time_limit"),
                                        max_time_limit)
    return MotionRequest(start=start, goal=goal, goal_pose=goal_pose, **own)


# ---- bodies ---------------------------------------------------------------------------------
def is_batch(body: Mapping[str, Any]) -> bool:
    """Whether ``body`` asks for many problems (``problems``) rather than one."""
    return isinstance(body, Mapping) and body.get("problems") is not None


def parse_motion_request(body: Mapping[str, Any], model: RobotModel, *,
                         max_time_limit: float = MAX_TIME_LIMIT_S,
                         ignore: Collection[str] = ()) -> MotionRequest:
    """One problem of ``model`` from ``body`` (``REQUEST_FIELDS``; keys in ``ignore``, such
    as a job's ``robot``, are skipped; a key set to None counts as absent). ``time_limit``
    defaults to ``DEFAULT_TIME_LIMIT_S`` or ``max_time_limit`` if less. ``FieldError``
    naming the field at fault."""
    if not isinstance(body, Mapping):
        raise FieldError((), "a motion request must be a JSON object")
    body = {k: v for k, v in body.items() if k not in ignore and v is not None}
    _known(body, REQUEST_FIELDS, ())
    settings = _settings(body, max_time_limit)
    return _problem({k: body[k] for k in ("start", "goal") if k in body}, model, settings, (),
                    max_time_limit)


def parse_motion_problems(body: Mapping[str, Any], model: RobotModel, *,
                          max_time_limit: float = MAX_TIME_LIMIT_S,
                          max_problems: int = MAX_PROBLEMS,
                          ignore: Collection[str] = ()) -> list[MotionRequest]:
    """The problems of ``body``: ``problems`` (each ``PROBLEM_FIELDS``; ``seed`` and
    ``time_limit`` default to the body's) sharing the body's other settings; or the one
    problem of a body with ``start`` and ``goal``. At most ``max_problems``."""
    if not isinstance(body, Mapping):
        raise FieldError((), "a motion request must be a JSON object")
    if not is_batch(body):
        return [parse_motion_request(body, model, max_time_limit=max_time_limit,
                                     ignore=ignore)]
    body = {k: v for k, v in body.items() if k not in ignore and v is not None}
    for key in ("start", "goal"):
        if key in body:
            raise FieldError((key,), "give start and goal, or problems (each with its own "
                                     "start and goal), not both")
    _known(body, (*_SHARED_FIELDS, "problems"), ())
    items = body["problems"]
    if not isinstance(items, Sequence) or isinstance(items, str | bytes):
        raise FieldError(("problems",), "must be a list of {start, goal} objects")
    if not 1 <= len(items) <= max_problems:
        raise FieldError(("problems",), f"give 1 to {max_problems} problems, got {len(items)}")
    settings = _settings(body, max_time_limit)
    return [_problem(item, model, settings, ("problems", i), max_time_limit)
            for i, item in enumerate(items)]
