"""Job kinds ``path`` (plan one obstacle-avoiding path, optionally for a robot's tool) and
``path_compare`` (every planner over many seeds, as paper 000's Tables 3 and 4).

Scenes are validated here, at the API edge, so a bad scene is a 422 naming the field
(``params.scene.obstacles.2.radius``, ``params.start``): the pydantic models check shapes
and signs per field, and ``start``/``goal`` are checked against the scene (inside an
obstacle, outside the bounds) by field validators that reuse ``planning.scene``'s messages.

``robot`` is optional, so the kind is registered with ``needs_robot=False``; when the service
attaches the model under ``_model`` it is used, else a built-in robot is looked up by id.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from ..fields import Point3 as Vec3
from .kinds import JobKind, Params, Progress, register

__all__ = ["PathParams", "PathCompareParams", "run_path", "run_path_compare"]

Algorithm = Literal["wolfpack_improved", "wolfpack", "ga", "aca", "afsa", "rrt_star", "auto"]
#: Most obstacles in one scene.
MAX_OBSTACLES = 1000
#: Parameter names the planners take besides their optimiser's fields.
_COMMON = {"waypoints", "penalty", "max_evaluations", "shortcut", "random_shortcuts"}
_OWN = {"auto": {"samples", "rel_offset", "rounds"},
        "rrt_star": {"samples", "step", "goal_bias", "gamma", "time_limit"}}


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class ObstacleIn(_Strict):
    """A sphere ``{center, radius}`` (``type`` optional), a box ``{type: "box", lower, upper}``
    or ``{type: "box", center, size}``, or a capsule ``{type: "capsule", a, b, radius}``."""

    type: Literal["sphere", "box", "capsule"] = "sphere"
    center: Vec3 | None = None
    radius: float | None = Field(None, gt=0, le=1e9, description="mm")
    lower: Vec3 | None = None
    upper: Vec3 | None = None
    size: list[Annotated[float, Field(gt=0, le=1e9)]] | None = Field(
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
        """The fields this type needs, and no others (messages from planning.scene)."""
        from planning.scene import obstacle_from_dict

        try:
            obstacle_from_dict(self.to_plain(), "obstacle")
        except ValueError as exc:
            raise ValueError(str(exc).removeprefix("obstacle.")) from None
        return self

    def to_plain(self) -> dict[str, Any]:
        return {k: v for k, v in self.model_dump().items() if v is not None}


class SceneIn(_Strict):
    bounds: list[Vec3] = Field(min_length=2, max_length=2,
                               description="[[xmin, ymin, zmin], [xmax, ymax, zmax]] mm")
    obstacles: list[ObstacleIn] = Field(default_factory=list, max_length=MAX_OBSTACLES)
    safety_margin: float = Field(0.0, ge=0, le=1e9, description="mm")

    @field_validator("bounds")
    @classmethod
    def _ordered(cls, v):
        if any(hi <= lo for lo, hi in zip(v[0], v[1])):
            raise ValueError("bounds[1] must exceed bounds[0] on every axis")
        return v

    def to_scene(self):
        """The ``planning.scene.Scene``; ValueError names ``obstacles[i].<field>``."""
        from planning.scene import Scene

        return Scene.create(self.bounds, [o.to_plain() for o in self.obstacles],
                            self.safety_margin)


class ArmOptions(_Strict):
    """Options of a path planned for a robot's tool (see ``planning.arm_paths``)."""

    link_radius: float | list[Annotated[float, Field(ge=0, le=1e6)]] = Field(
        60.0, description="mm, one number or one per link")
    spacing: float = Field(10.0, gt=0, le=1e6, description="mm between IK samples")
    waypoint_spacing: float = Field(25.0, gt=0, le=1e6, description="mm between waypoints")
    duration: float = Field(10.0, gt=0, le=1e6, description="s of the joint trajectory")
    clearance_slack: float = Field(5.0, ge=0, le=1e6, description="mm")
    keep_out_radius: float | None = Field(None, gt=0, le=1e9, description="mm")
    dt: float | None = Field(None, gt=0, le=1e3, description="s between trajectory samples")


def _endpoint(v, info: ValidationInfo):
    scene = info.data.get("scene")
    if scene is None:  # the scene itself failed; its error is reported
        return v
    scene.to_scene().check_endpoint(v, info.field_name)
    return v


def _algorithm_params(v, info: ValidationInfo):
    if v is None:
        return v
    algorithm = info.data.get("algorithm")
    if algorithm is None:
        return v
    if algorithm in _OWN:
        unknown = set(v) - _OWN[algorithm]
        if unknown:
            raise ValueError(f"{sorted(unknown)[0]} is not a parameter of {algorithm}; "
                             f"known: {', '.join(sorted(_OWN[algorithm]))}")
        return v
    from planning.paths import make_optimiser

    make_optimiser(algorithm, {k: x for k, x in v.items() if k not in _COMMON})
    return v


class _SceneTask(Params):
    """A scene with free start and goal points (mm), and the seed of the planners."""

    scene: SceneIn
    start: Vec3
    goal: Vec3
    seed: int = Field(0, ge=0, le=2**32 - 1)

    @field_validator("start", "goal")
    @classmethod
    def _free(cls, v, info: ValidationInfo):
        return _endpoint(v, info)


class PathParams(_SceneTask):
    algorithm: Algorithm = "auto"
    params: dict[str, Any] | None = Field(
        None, description="Planner parameters (defaults: paper 000's); see planning.paths")
    robot: str | None = Field(None, description="Robot id: plan for its tool and check the "
                                                "whole arm")
    arm: ArmOptions | None = None

    @field_validator("params")
    @classmethod
    def _params_known(cls, v, info: ValidationInfo):
        return _algorithm_params(v, info)


def _model(params: dict[str, Any]):
    from kinematics.library import builtin_model
    from kinematics.model import RobotModel

    if params.get("_model") is not None:
        return RobotModel.from_dict(params["_model"])
    try:
        return builtin_model(params["robot"])
    except KeyError:
        raise ValueError(f"robot '{params['robot']}': its model was not attached to the job "
                         "and it is not a built-in robot") from None


def run_path(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Plan one path; with ``robot``, for that robot's tool (reach, whole-arm clearance,
    joint trajectory, cylinder lengths)."""
    from planning.arm_paths import plan_arm_path
    from planning.paths import plan_path

    scene = SceneIn.model_validate(params["scene"]).to_scene()

    def report(f: float) -> None:
        progress(0.99 * f, "planning")

    if params.get("robot"):
        arm = ArmOptions.model_validate(params.get("arm") or {})
        opts = arm.model_dump(exclude={"dt"})
        res = plan_arm_path(_model(params), scene, params["start"], params["goal"],
                            params["algorithm"], params["seed"], params.get("params"),
                            report, **opts)
        out = res.to_dict(arm.dt)
        out["robot"] = params["robot"]
    else:
        out = plan_path(scene, params["start"], params["goal"], params["algorithm"],
                        params["seed"], params.get("params"), report).to_dict()
        out.update(joint_path=None, trajectory=None, cylinders=None)
    progress(1.0, "done")
    return out


class PathCompareParams(_SceneTask):
    algorithms: list[Algorithm] = Field(
        default_factory=lambda: ["wolfpack_improved", "wolfpack", "aca", "ga", "afsa"],
        min_length=1, max_length=7)
    runs: int = Field(10, ge=1, le=100, description="Seeds per algorithm")
    params: dict[str, dict[str, Any]] | None = Field(
        None, description="Parameters per algorithm, e.g. {'wolfpack': {'iterations': 20}}")

    @field_validator("params")
    @classmethod
    def _known(cls, v, info: ValidationInfo):
        algorithms = info.data.get("algorithms")
        if v is None or algorithms is None:
            return v
        for name, p in v.items():
            if name not in algorithms:
                raise ValueError(f"{name} is not among the algorithms compared")
            _algorithm_params(p, _Info(name))
        return v


class _Info:
    """Just enough of ValidationInfo for ``_algorithm_params``."""

    def __init__(self, algorithm: str) -> None:
        self.data = {"algorithm": algorithm}


def run_path_compare(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Every algorithm over ``runs`` seeds: rows of best/mean length, mean time, successes."""
    from planning.path_compare import compare_planners

    scene = SceneIn.model_validate(params["scene"]).to_scene()
    rows = compare_planners(scene, params["start"], params["goal"], params["algorithms"],
                            params["runs"], params["seed"], params.get("params"),
                            lambda f: progress(0.99 * f, "comparing"))
    progress(1.0, "done")
    return {"rows": [r.to_dict() for r in rows], "runs": params["runs"]}


register(JobKind("path", PathParams, run_path,
                 "Obstacle-avoiding path (paper 000's planners); optional robot tool path "
                 "with whole-arm clearance, joint trajectory and cylinder lengths"))
register(JobKind("path_compare", PathCompareParams, run_path_compare,
                 "Every path planner over many seeds (paper 000, Tables 3-4)"))
