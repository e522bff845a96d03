"""Job kinds ``path`` (plan one obstacle-avoiding path, optionally for a robot's tool) and
``path_compare`` (every planner over many seeds, as paper 000's Tables 3 and 4).

Scenes are validated here, at the API edge, so a bad scene is a 422 naming the field
(``params.scene.obstacles.2.radius``, ``params.start``): the pydantic models check shapes
and signs per field, and ``start``/``goal`` are checked against the scene (inside an
obstacle, outside the bounds) by field validators that reuse ``planning.paths.scene``'s messages.

``robot`` is optional, so the kind is registered with ``needs_robot=False``; when the service
attaches the robot's model it is used, else a built-in robot is looked up by id. A robot's
move is planned by ``planning.motion.arm_motion.plan_arm_motion``: the tool path when the arm
can follow it, else (or with ``arm.joint_space: "always"``, or a goal configuration
``arm.q_goal``) a joint-space motion in the same obstacles; ``planner`` in the result says
which. ``start`` and ``goal`` may be left out when ``arm.q_start`` / ``arm.q_goal`` give the
configurations.

A stored scene (``scene.id``) becomes conservative obstacles for the tool path (bounding
boxes of meshes, boxes over point clouds) and, up to ``MAX_SCENE_OBJECTS_BYTES`` of JSON, its
own objects (``scene.objects``, stored meshes inline) for the joint-space planner.

The scene is built once per process: ``SceneIn.to_scene()`` keeps what it built, so the
checks of ``start`` and ``goal`` and the run (in the worker, on the params rebuilt there)
share one ``planning.paths.scene.Scene``.

Planner ``params`` are free-form in the contract but checked against the planner's bounded
model (``planner_params``): every knob capped, and one batch of obstacle checks within
``MAX_BATCH_BYTES`` of memory.

``path_compare`` divides (``path_compare_graph``): a few seeds of one algorithm per step
(``compare_parts``; each run depends on its seed alone) and a step making the rows of their
outcomes, in seed order, as ``planning.paths.compare.compare_planners`` does.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    WithJsonSchema,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from planning.motion import PLANNERS as MOTION_PLANNERS
from planning.motion.arm_motion import DEFAULT_JOINT_TIME_LIMIT, JOINT_SPACE_MODES
from planning.registry import algorithm_names

from ..fields import MAX_COORDINATE_MM, JointVector, StrictModel
from ..fields import Point3 as Vec3
from .caps import ParamsLimitError
from .graph import Ref, Step, run_inline
from .kinds import (
    MAX_SEED,
    XYZ,
    JobKind,
    Params,
    Progress,
    Result,
    Submission,
    absent_when_none,
    pick,
    register,
)
from .planner_params import PATH_KNOBS, check_batch_memory, knobs_schema, path_knobs

__all__ = ["PathParams", "PathResult", "PathCompareParams", "PathCompareResult", "run_path",
           "run_path_compare", "path_compare_graph", "compare_parts", "prepare_path"]

#: The path planners: the ``path`` family of ``planning.registry``.
Algorithm = Literal[algorithm_names("path")]  # type: ignore[valid-type]
#: Most obstacles in one scene.
MAX_OBSTACLES = 1000
#: Largest obstacle radius or box edge, and safety margin (mm).
MAX_SIZE_MM = MAX_COORDINATE_MM
#: Most samples of a returned joint trajectory (``arm.duration / arm.dt``).
MAX_TRAJECTORY_SAMPLES = 100_000
#: Largest link radius (mm) of the whole-arm check.
MAX_LINK_RADIUS_MM = 10_000.0
#: Longest search of the joint-space planner (s) of one arm path.
MAX_JOINT_TIME_LIMIT_S = 600.0
#: Most JSON bytes of a stored scene's objects recorded in a path job for the joint-space
#: planner (beyond it, that planner avoids the conservative obstacles too).
MAX_SCENE_OBJECTS_BYTES = 4 * 1024 * 1024

#: The JSON schema of ``path``'s free-form ``params``: one of the planners' bounded models.
PLANNER_PARAMS_SCHEMA = knobs_schema(
    PATH_KNOBS, "Planner parameters (defaults: paper 000's), by algorithm; see "
    "planning.paths")


class ObstacleIn(StrictModel):
    """A sphere ``{center, radius}`` (``type`` optional), a box ``{type: "box", lower, upper}``
    or ``{type: "box", center, size}``, or a capsule ``{type: "capsule", a, b, radius}``."""

    type: Literal["sphere", "box", "capsule"] = "sphere"
    center: Vec3 | None = None
    radius: float | None = Field(None, gt=0, le=MAX_SIZE_MM, description="mm")
    lower: Vec3 | None = None
    upper: Vec3 | None = None
    size: list[Annotated[float, Field(gt=0, le=MAX_SIZE_MM)]] | None = Field(
        None, min_length=3, max_length=3, description="box edge lengths, mm")
    a: Vec3 | None = None
    b: Vec3 | None = None

    @field_validator("upper")
    @classmethod
    def _upper_above_lower(cls, v, info: ValidationInfo):
        lower = info.data.get("lower")
        if v is not None and lower is not None and any(u <= lo for u, lo in zip(v, lower)):
            raise ValueError("must exceed lower on every axis")
        return v

    @model_validator(mode="after")
    def _complete(self):
        """The fields this type needs, and no others (planning.geometry.obstacles' checks,
        which name the field within the obstacle)."""
        from planning.geometry.obstacles import obstacle_from_dict

        obstacle_from_dict(self.to_plain())
        return self

    def to_plain(self) -> dict[str, Any]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


class SceneIn(StrictModel):
    id: str | None = Field(None, max_length=64, description="A stored scene (POST /scenes) "
                           "whose objects become the obstacles (conservatively: see "
                           "docs/API.md); the job records the obstacles it used")
    bounds: list[Vec3] = Field(min_length=2, max_length=2,
                               description="[[xmin, ymin, zmin], [xmax, ymax, zmax]] mm")
    obstacles: list[ObstacleIn] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    safety_margin: float = Field(0.0, ge=0, le=MAX_SIZE_MM, description="mm")
    objects: list[dict[str, Any]] | None = Field(
        None, max_length=MAX_OBSTACLES, description="The stored scene's own objects "
        "(planning.collision's format, meshes inline), filled in from id at submission: "
        "what a robot's joint-space motion avoids (the obstacles cover them, never smaller)")

    _scene: Any = PrivateAttr(None)
    _objects: Any = PrivateAttr(None)

    @field_validator("bounds")
    @classmethod
    def _ordered(cls, v):
        if any(hi <= lo for lo, hi in zip(v[0], v[1])):
            raise ValueError("bounds[1] must exceed bounds[0] on every axis")
        return v

    @model_validator(mode="after")
    def _objects_of_a_stored_scene(self) -> SceneIn:
        # Filled in from a stored scene, which was validated when it was stored.
        if self.objects is not None and self.id is None:
            raise ValueError("objects: only a stored scene's (with its id) are recorded")
        return self

    def to_scene(self):
        """The ``planning.paths.scene.Scene`` (built on the first call, then kept); ValueError
        names ``obstacles[i].<field>``."""
        from planning.paths.scene import Scene

        if self._scene is None:
            self._scene = Scene.create(self.bounds, [o.to_plain() for o in self.obstacles],
                                       self.safety_margin)
        return self._scene

    def collision_scene(self):
        """The stored scene's objects as a ``planning.collision.CollisionScene`` (built once),
        None without them; ``FieldError`` at ``("objects", i, ...)``."""
        if self.objects is None:
            return None
        if self._objects is None:
            from planning.collision import CollisionScene

            self._objects = CollisionScene.from_dicts(self.objects)
        return self._objects


class ArmOptions(StrictModel):
    """Options of a path planned for a robot's tool (see ``planning.paths.arm``)."""

    link_radius: (Annotated[float, Field(ge=0, le=MAX_LINK_RADIUS_MM)]
                  | Annotated[list[Annotated[float, Field(ge=0, le=MAX_LINK_RADIUS_MM)]],
                              Field(min_length=1, max_length=64)]) = Field(
        60.0, description="mm, one number or one per link")
    spacing: float = Field(10.0, ge=1, le=1e5, description="mm between IK samples")
    waypoint_spacing: float = Field(25.0, ge=1, le=1e6, description="mm between waypoints")
    timing: Literal["optimal", "uniform"] = Field(
        "optimal", description="'optimal': the fastest joint trajectory within the robot's "
        "speed limits (and its cylinders' and pump's), acceleration and jerk; 'uniform': "
        "the spline stretched to last duration")
    duration: float = Field(10.0, gt=0, le=86_400, description="s of the joint trajectory "
                            "with timing 'uniform'")
    acceleration: (Annotated[float, Field(gt=0, le=1e6)]
                   | Annotated[list[Annotated[float, Field(gt=0, le=1e6)]],
                               Field(min_length=1, max_length=64)] | None) = Field(
        None, description="Joint acceleration limits of 'optimal' timing, rad/s² or mm/s² "
        "(one number or one per joint; default 1 rad/s², 500 mm/s²)")
    jerk: (Annotated[float, Field(gt=0, le=1e8)]
           | Annotated[list[Annotated[float, Field(gt=0, le=1e8)]],
                       Field(min_length=1, max_length=64)] | None) = Field(
        None, description="Joint jerk limits of 'optimal' timing, rad/s³ or mm/s³ (default "
        "5 rad/s³, 2500 mm/s³)")
    clearance_slack: float = Field(5.0, ge=0, le=1e4, description="mm")
    keep_out_radius: float | None = Field(None, gt=0, le=MAX_SIZE_MM, description="mm")
    q_start: JointVector | None = Field(
        None, description="Joint values to start from (rad / mm; default: position IK of "
        "start); start may then be left out")
    q_goal: JointVector | None = Field(
        None, description="Joint values to end at (rad / mm): the move is then planned in "
        "joint space; goal may be left out")
    joint_space: Literal[JOINT_SPACE_MODES] = Field(  # type: ignore[valid-type]
        "fallback", description="'fallback': plan the tool path, and a joint-space motion "
        "in the same obstacles when the arm cannot follow it (out of reach, no IK, a link "
        "in collision); 'always': the joint-space motion only; 'never': the tool path only")
    joint_time_limit: float = Field(
        DEFAULT_JOINT_TIME_LIMIT, gt=0, le=MAX_JOINT_TIME_LIMIT_S,
        description="s of joint-space search (over the goal configurations tried)")
    joint_planner: Literal[MOTION_PLANNERS] = Field(  # type: ignore[valid-type]
        "auto", description="The joint-space planner (planning.motion)")
    dt: float | None = Field(None, ge=1e-3, le=1e3, description="s between trajectory "
                             f"samples (at most {MAX_TRAJECTORY_SAMPLES:,} samples)")

    @model_validator(mode="after")
    def _samples(self) -> ArmOptions:
        if self.dt is not None and self.duration / self.dt > MAX_TRAJECTORY_SAMPLES:
            raise ValueError(f"dt: duration / dt is {self.duration / self.dt:,.0f} samples; "
                             f"at most {MAX_TRAJECTORY_SAMPLES:,}")
        return self


#: Margin (mm) of the bounds derived from a stored scene, around its objects and endpoints.
SCENE_BOUNDS_MARGIN_MM = 500.0


def path_obstacles(objects: Any) -> list[dict[str, Any]]:
    """Obstacles of a point-path scene (spheres, axis-aligned boxes, capsules) covering a
    stored scene's objects (``planning.collision`` ``SceneObject``s), never smaller: spheres
    and capsules as they are, a box as its axis-aligned bounding box, a cylinder as the capsule
    along its axis, a mesh as its bounding box, a point cloud as boxes over a coarse grid
    (at most 400): each shape's ``path_cover``."""
    out: list[dict[str, Any]] = []
    for o in objects:  # each shape's own cover (planning.geometry's ShapeKind.path_cover)
        out.extend(o.kind.path_cover(o))
    return out


def scene_objects(objects: Any) -> list[dict[str, Any]] | None:
    """A stored scene's objects in the API format with stored meshes inline (a worker has no
    store), or None when their JSON would exceed ``MAX_SCENE_OBJECTS_BYTES``."""
    import json

    out = []
    for o in objects:
        d = o.to_dict()
        if o.type == "mesh" and "mesh" in d:
            del d["mesh"]
            d.update(vertices=o.vertices.tolist(), faces=o.faces.tolist())
        out.append(d)
    size = len(json.dumps(out, separators=(",", ":")).encode())
    return out if size <= MAX_SCENE_OBJECTS_BYTES else None


def scene_params(stored: Any, given: dict[str, Any], endpoints: list) -> dict[str, Any]:
    """A path job's inline ``scene`` from a stored scene: its obstacles (``path_obstacles``),
    its own objects for a robot's joint-space motion (``scene_objects``) and, unless
    ``given`` has them, bounds around the obstacles and the endpoints."""
    obstacles = path_obstacles(stored.objects)
    out = {**{k: v for k, v in given.items() if k != "objects"}, "obstacles": obstacles}
    objects = scene_objects(stored.objects)
    if objects is not None:
        out["objects"] = objects
    if "bounds" not in given:
        pts = [np.asarray(e, dtype=float).reshape(1, 3) for e in endpoints
               if isinstance(e, list) and len(e) == 3
               and all(isinstance(x, int | float) and not isinstance(x, bool) for x in e)]
        for ob in obstacles:
            if ob["type"] == "sphere":
                c, r = np.asarray(ob["center"]), ob["radius"]
                pts.append(np.stack([c - r, c + r]))
            elif ob["type"] == "box":
                pts.append(np.asarray([ob["lower"], ob["upper"]]))
            else:
                ends, r = np.asarray([ob["a"], ob["b"]]), ob["radius"]
                pts.append(np.vstack([ends - r, ends + r]))
        P = np.vstack(pts) if pts else np.zeros((1, 3))
        m = SCENE_BOUNDS_MARGIN_MM
        out["bounds"] = [(P.min(axis=0) - m).tolist(), (P.max(axis=0) + m).tolist()]
    return out


def prepare_path(params: dict[str, Any], submission: Submission) -> dict[str, Any]:
    """The ``prepare`` hook of ``path`` and ``path_compare``: params whose ``scene`` names a
    stored scene (``"scene": "id"`` or ``{"id": ...}``) with that scene's obstacles filled
    in (``scene_params``); ``ParamsLimitError`` for an unknown scene (404) or a scene given
    both ways (422)."""
    scene = params.get("scene")
    if isinstance(scene, str):
        scene = {"id": scene}
    if not isinstance(scene, dict) or not isinstance(scene.get("id"), str):
        return params
    if "obstacles" in scene:
        raise ParamsLimitError(["params", "scene", "obstacles"], "give a stored scene's id "
                               "or obstacles, not both")
    scenes = submission.scenes
    try:
        stored = scenes.get(scene["id"]) if scenes is not None else None
    except KeyError:
        stored = None
    if stored is None:
        raise ParamsLimitError(["params", "scene", "id"], f"unknown scene '{scene['id']}'", 404)
    return {**params, "scene": scene_params(stored, scene,
                                            [params.get("start"), params.get("goal")])}


def _endpoint(v, info: ValidationInfo):
    scene = info.data.get("scene")
    if scene is None or v is None:  # the scene itself failed (its error is reported), or
        return v                      # a robot path gives the configuration instead
    scene.to_scene().check_endpoint(v, info.field_name)
    return v


def _batch_memory(scene: SceneIn | None, runs: dict[str, dict | None]) -> None:
    """Each planner's largest batch of obstacle checks fits the memory cap."""
    if scene is None:
        return
    types = [o.type for o in scene.obstacles]
    for algorithm, knobs in runs.items():
        check_batch_memory(algorithm, knobs, types)


class _SceneTask(Params):
    """A scene with free start and goal points (mm), and the seed of the planners."""

    scene: SceneIn
    start: Vec3
    goal: Vec3
    seed: int = Field(0, ge=0, le=MAX_SEED)

    @field_validator("start", "goal")
    @classmethod
    def _free(cls, v, info: ValidationInfo):
        return _endpoint(v, info)


class PathParams(_SceneTask):
    start: Vec3 | None = Field(None, description="mm; may be left out with arm.q_start")
    goal: Vec3 | None = Field(None, description="mm; may be left out with arm.q_goal")
    algorithm: Algorithm = "auto"
    params: Annotated[dict[str, Any] | None, WithJsonSchema(PLANNER_PARAMS_SCHEMA)] = None
    robot: str | None = Field(None, max_length=200,
                              description="Robot id: plan for its tool and check the whole arm")
    arm: ArmOptions | None = None

    @field_validator("params")
    @classmethod
    def _params_known(cls, v, info: ValidationInfo):
        algorithm = info.data.get("algorithm")
        return v if algorithm is None else path_knobs(algorithm, v)

    @model_validator(mode="after")
    def _memory(self) -> PathParams:
        _batch_memory(self.scene, {self.algorithm: self.params})
        return self

    @model_validator(mode="after")
    def _endpoints(self) -> PathParams:
        for name in ("start", "goal"):
            if getattr(self, name) is None and getattr(self.arm, f"q_{name}", None) is None:
                raise _field_error(name, "missing", f"{name} is required (a robot path may "
                                   f"give arm.q_{name} instead)")
        if (self.arm is not None and (self.arm.q_start or self.arm.q_goal)
                and not self.robot):
            raise _field_error("robot", "missing", "arm.q_start and arm.q_goal need a robot")
        if not self.robot and self.scene.objects is not None:
            self.scene.objects = None  # only a robot's joint-space motion uses them
        return self


def _field_error(loc: str, kind: str, message: str) -> ValidationError:
    """An error of a check across fields, at the field it names (not at the model)."""
    return ValidationError.from_exception_data("PathParams", [
        {"type": PydanticCustomError(kind, message), "loc": (loc,), "input": None}])


class PathTrajectory(Result):
    """The joint trajectory, sampled every ``arm.dt`` s (default duration / 200)."""

    t: list[float] = Field(description="s")
    q: list[list[float]] = Field(description="rad / mm per sample")
    qd: list[list[float]] = Field(description="rad/s / mm/s per sample")
    qdd: list[list[float]] = Field(description="rad/s^2 / mm/s^2 per sample")
    waypoints: list[list[float]] = Field(description="The joint waypoints it passes through")


class PathCylinders(Result):
    lengths: dict[str, list[float]] = Field(description="Length per cylinder along the tool "
                                            "samples, mm")
    within_stroke: bool | None = Field(description="Every length within its stroke")


class PathResult(Result):
    """A planned path; with ``robot``, for that robot's tool (``planning.paths.arm``)."""

    path: list[XYZ] = Field(description="Start to goal, mm; empty when no clear path was "
                            "found")
    length: float | None = Field(description="mm (null on failure)")
    min_clearance: float | None = Field(description="mm (null: no obstacles)")
    runtime_s: float
    convergence: list[float | None] = Field(description="Best cost after each iteration")
    algorithm: str
    evaluations: int
    success: bool
    status: str = Field(description="How planning ended (planning.status.PlanStatus): ok, "
                        "no_path, budget_spent, collision, unreachable, out_of_limits, "
                        "invalid_input")
    message: str
    raw_length: float | None = Field(description="mm, before shortcutting")
    joint_path: list[list[float]] | None = Field(description="Joints at the tool samples "
                                                 "(robot paths; null otherwise)")
    trajectory: PathTrajectory | None = Field(description="Robot paths; null otherwise")
    cylinders: PathCylinders | None = Field(description="Robot paths of robots with "
                                            "cylinders; null otherwise")
    robot: str | None = absent_when_none("Robot paths only")
    planner: Literal["tool_space", "joint_space"] | None = absent_when_none(
        "Robot paths only: what produced the motion, 'tool_space' (the tool path, followed "
        "by IK) or 'joint_space' (planning.motion; the tool path is the tool's route along "
        "it)")
    arm_min_clearance: float | None = absent_when_none(
        "Least clearance of the whole arm, mm (robot paths only)")
    tool_samples: list[XYZ] | None = absent_when_none(
        "Dense tool positions along the path, mm (robot paths only)")


def run_path(params: PathParams, progress: Progress) -> PathResult:
    """Plan one path; with ``robot``, for that robot's tool (reach, whole-arm clearance,
    joint trajectory, cylinder lengths)."""
    from planning.motion.arm_motion import plan_arm_motion
    from planning.paths import plan_path

    scene = params.scene.to_scene()

    def report(f: float) -> None:
        progress(0.99 * f, "planning")

    if params.robot:
        arm = params.arm or ArmOptions()
        res = plan_arm_motion(params.robot_model(), scene, params.start, params.goal,
                              params.algorithm, params.seed, params.params, report,
                              objects=params.scene.collision_scene(),
                              **arm.model_dump(exclude={"dt"}))
        out = PathResult(**pick(PathResult, res.to_dict(arm.dt) | {"robot": params.robot}))
    else:
        res = plan_path(scene, params.start, params.goal, params.algorithm, params.seed,
                        params.params, report)
        out = PathResult(**pick(PathResult, res.to_dict()), joint_path=None, trajectory=None,
                         cylinders=None)
    progress(1.0, "done")
    return out


class PathCompareParams(_SceneTask):
    algorithms: list[Algorithm] = Field(
        default_factory=lambda: ["wolfpack_improved", "wolfpack", "aca", "ga", "afsa"],
        min_length=1, max_length=7)
    runs: int = Field(10, ge=1, le=100, description="Seeds per algorithm")
    params: Annotated[dict[str, dict[str, Any]] | None, WithJsonSchema({
        "anyOf": [{"type": "object", "additionalProperties": False,
                   "properties": {name: model.model_json_schema()
                                  for name, model in PATH_KNOBS.items()}},
                  {"type": "null"}],
        "description": "Parameters per algorithm, e.g. {'wolfpack': {'iterations': 20}}"})
    ] = None

    @field_validator("params")
    @classmethod
    def _known(cls, v, info: ValidationInfo):
        algorithms = info.data.get("algorithms")
        if v is None or algorithms is None:
            return v
        for name in v:
            if name not in algorithms:
                raise ValueError(f"{name} is not among the algorithms compared")
        return {name: path_knobs(name, p, f"params.{name}", (name,)) for name, p in v.items()}

    @model_validator(mode="after")
    def _memory(self) -> PathCompareParams:
        _batch_memory(self.scene, {a: (self.params or {}).get(a) for a in self.algorithms})
        self.scene.objects = None  # a robot's joint-space motion would use them; no robot
        return self


class CompareRow(Result):
    """One algorithm over ``runs`` seeds (paper 000, Tables 3 and 4); null where no run
    succeeded."""

    algorithm: str
    runs: int
    successes: int
    best_length: float | None = Field(description="mm")
    mean_length: float | None = Field(description="mm")
    mean_raw_length: float | None = Field(description="mm, before shortcutting")
    mean_time_s: float | None
    mean_evaluations: float | None


class PathCompareResult(Result):
    rows: list[CompareRow] = Field(description="One row per algorithm, in order")
    runs: int


#: Seconds of one run of each planner with its default parameters (paper 000's toy scene,
#: one core): what a step of a path_compare job weighs, and how many runs it takes.
RUN_SECONDS = {"wolfpack_improved": 1.9, "wolfpack": 3.7, "ga": 0.03, "aca": 0.4,
               "afsa": 1.4, "rrt_star": 1.0, "auto": 0.3}
#: A step of a path_compare job takes about this many seconds of runs of one algorithm ...
COMPARE_PART_SECONDS = 4.0
#: ... and at most this many runs.
COMPARE_PART_RUNS = 10


def compare_part_runs(algorithm: str) -> int:
    """Runs of ``algorithm`` per step: ``COMPARE_PART_SECONDS`` of them, 1 to
    ``COMPARE_PART_RUNS``."""
    seconds = RUN_SECONDS.get(algorithm, 1.0)
    return max(1, min(COMPARE_PART_RUNS, int(COMPARE_PART_SECONDS / seconds + 1e-9)))


def compare_parts(params: PathCompareParams) -> list[tuple[str, int, int]]:
    """The job's parts: ``(algorithm, first run, end run)`` by algorithm in order, each
    ``compare_part_runs(algorithm)`` runs (the last of an algorithm fewer)."""
    out = []
    for a in params.algorithms:
        size = compare_part_runs(a)
        out += [(a, r, min(params.runs, r + size)) for r in range(0, params.runs, size)]
    return out


def path_compare_graph(params: PathCompareParams) -> list[Step]:
    """The steps of a path_compare job: one algorithm's runs a few seeds at a time
    (``compare_parts``; one step when that is all), and a step making the rows."""
    parts = compare_parts(params)
    if len(parts) == 1:
        return [Step(run_path_compare_whole)]
    steps = [Step(path_compare_part, (a, r0, r1), weight=(r1 - r0) * RUN_SECONDS.get(a, 1.0),
                  label=f"{a}, runs {r0 + 1}-{r1}") for a, r0, r1 in parts]
    steps.append(Step(path_compare_result, ([Ref(i) for i in range(len(parts))],),
                      weight=0.01, label="rows"))
    return steps


def path_compare_part(params: PathCompareParams, algorithm: str, first: int, end: int,
                      progress: Progress) -> list:
    """Runs ``first..end-1`` (seeds ``seed + r``) of ``algorithm``:
    ``planning.paths.compare.RunOutcome``\\ s."""
    from planning.paths.compare import check_compare, compare_runs

    check_compare(params.algorithms, params.runs, params.params)
    return compare_runs(params.scene.to_scene(), params.start, params.goal, algorithm,
                        [params.seed + r for r in range(first, end)],
                        (params.params or {}).get(algorithm),
                        lambda f: progress(f, "planning"))


def path_compare_result(params: PathCompareParams, outcomes: list,
                        progress: Progress) -> PathCompareResult:
    """The rows of the parts' outcomes (``compare_parts``' order)."""
    from planning.paths.compare import compare_row

    runs: dict[str, list] = {a: [] for a in params.algorithms}
    for (a, _, _), part in zip(compare_parts(params), outcomes, strict=True):
        runs[a].extend(part)
    rows = [compare_row(a, runs[a]) for a in params.algorithms]
    progress(1.0, "done")
    return _compare_result(params, rows)


def run_path_compare_whole(params: PathCompareParams, progress: Progress) -> PathCompareResult:
    """Every algorithm over ``runs`` seeds in one step (``compare_planners``)."""
    from planning.paths.compare import compare_planners

    rows = compare_planners(params.scene.to_scene(), params.start, params.goal,
                            params.algorithms, params.runs, params.seed, params.params,
                            lambda f: progress(0.99 * f, "comparing"))
    progress(1.0, "done")
    return _compare_result(params, rows)


def _compare_result(params: PathCompareParams, rows: list) -> PathCompareResult:
    return PathCompareResult(rows=[CompareRow(**pick(CompareRow, r.to_dict())) for r in rows],
                             runs=params.runs)


def run_path_compare(params: PathCompareParams, progress: Progress) -> PathCompareResult:
    """Every algorithm over ``runs`` seeds: rows of best/mean length, mean time, successes
    (``path_compare_graph``: the same rows however the runs are spread over workers)."""
    return run_inline(path_compare_graph(params), params, progress)


register(JobKind("path", PathParams, PathResult, run_path,
                 "Obstacle-avoiding path (paper 000's planners); optional robot tool path "
                 "with whole-arm clearance, joint trajectory and cylinder lengths",
                 prepare=prepare_path))
register(JobKind("path_compare", PathCompareParams, PathCompareResult, run_path_compare,
                 "Every path planner over many seeds (paper 000, Tables 3-4)",
                 graph=path_compare_graph, prepare=prepare_path))
