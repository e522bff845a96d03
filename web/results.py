"""A finished job's result turned into what the viewer draws: a ``Plan``.

Pure data, no viser: every kind the viewer can show maps its params and result (the JSON of
``GET /jobs/{id}/result``, shapes as in docs/API.md) to point clouds, polylines, obstacles and
arm motions in mm. ``plan_from_result`` raises ``ValueError`` naming the key at fault when a
result does not have the documented shape.

Shapes read, per kind (keys marked ? are optional):

* ``workspace``: result ``points`` (and ``min``, ``max``, ``radial``, ``vertical``,
  ``volume``, ``samples`` for the summary); the robot is ``params.robot``.
* ``path``: params ``scene {"bounds", "obstacles"}``, ``start``?, ``goal``?, ``robot``?;
  result ``path [[x, y, z], ...]``, ``joint_path``? ``[[q...], ...]`` or ``trajectory``?
  ``{"t", "q"}`` (the arm moves along it when the params name a robot).
* ``sequence``: params ``holes``, ``start``?, ``robot``?; result ``order`` and, if present,
  ``joint_path`` / ``trajectory`` as for ``path``.
* ``multiarm``: params ``rig``, ``holes {arm: [[x, y, z], ...]}``; result per-arm joint
  trajectories under ``trajectories`` or ``arms``: ``{arm: {"t"?, "q", "order"?} | [[q...]]}``
  (a shared ``t`` may sit at the top level), ``min_distance``?, ``collisions``?.
* ``tracking``: params ``robot``; result ``q [[...]]`` (the arm's actual motion), ``errors``?,
  ``t``? or ``dt``?, and the desired tool path under ``x_desired``? or ``desired``? (without
  it only the actual tool path is drawn, and the summary says so).

Timing: a joint path without times is played at ``DEFAULT_SECONDS`` in total; tracking samples
without ``t`` are ``dt`` apart (result, then params, else ``DEFAULT_TRACKING_DT``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.fk import fk
from kinematics.model import RobotModel

__all__ = [
    "DRAWABLE_KINDS",
    "DEFAULT_SECONDS",
    "DEFAULT_TRACKING_DT",
    "Motion",
    "Cloud",
    "Polyline",
    "Spheres",
    "Box",
    "Capsule",
    "Plan",
    "plan_from_result",
]

DRAWABLE_KINDS = ("workspace", "path", "sequence", "multiarm", "tracking")
#: Playback length (s) of a joint path that carries no times.
DEFAULT_SECONDS = 5.0
#: Sample spacing (s) of a tracking run whose result carries neither ``t`` nor ``dt``
#: (``planning.tracking.TrackingConfig``'s default control period).
DEFAULT_TRACKING_DT = 0.1

PATH_COLOR = (20, 160, 60)
START_COLOR = (30, 120, 230)
GOAL_COLOR = (230, 50, 50)
OBSTACLE_COLOR = (200, 70, 70)
HOLE_COLOR = (250, 200, 30)
DESIRED_COLOR = (30, 120, 230)
ACTUAL_COLOR = (230, 80, 30)
ARM_COLORS = {"left": (30, 120, 230), "middle": (20, 160, 60), "right": (200, 60, 160)}


@dataclass(frozen=True)
class Motion:
    """One arm's motion: times ``t (S,)`` s, increasing from 0, and ``q (S, dof)``."""

    t: np.ndarray
    q: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def at(self, time: float) -> np.ndarray:
        """``q (dof,)`` at ``time`` s, linear between samples, held outside ``[0, duration]``."""
        return np.array([np.interp(time, self.t, col) for col in self.q.T])


@dataclass(frozen=True)
class Cloud:
    """Points ``(N, 3)`` mm, coloured by height."""

    name: str
    points: np.ndarray


@dataclass(frozen=True)
class Polyline:
    """A polyline through ``points (N, 3)`` mm."""

    name: str
    points: np.ndarray
    color: tuple[int, int, int]


@dataclass(frozen=True)
class Spheres:
    """Balls ``centers (K, 3)``, ``radii (K,)`` mm."""

    name: str
    centers: np.ndarray
    radii: np.ndarray
    color: tuple[int, int, int]
    opacity: float | None = None


@dataclass(frozen=True)
class Box:
    """An axis-aligned box ``lower (3,)``, ``upper (3,)`` mm; ``wireframe`` for scene
    bounds."""

    name: str
    lower: np.ndarray
    upper: np.ndarray
    color: tuple[int, int, int]
    wireframe: bool = False


@dataclass(frozen=True)
class Capsule:
    """Points within ``radius`` of the segment ``a``-``b`` (mm)."""

    name: str
    a: np.ndarray
    b: np.ndarray
    radius: float
    color: tuple[int, int, int]


@dataclass(frozen=True)
class Plan:
    """What to draw for one job. ``robot``: robot or rig id to show with it (None: keep the
    current one); ``motions`` by arm (``""`` for a single robot, the arm name in a rig);
    ``summary`` Markdown for the GUI. Node names are relative to the plan's root."""

    job: str
    kind: str
    robot: str | None = None
    clouds: tuple[Cloud, ...] = ()
    polylines: tuple[Polyline, ...] = ()
    spheres: tuple[Spheres, ...] = ()
    boxes: tuple[Box, ...] = ()
    capsules: tuple[Capsule, ...] = ()
    motions: dict[str, Motion] = field(default_factory=dict)
    summary: str = ""

    @property
    def duration(self) -> float:
        return max((m.duration for m in self.motions.values()), default=0.0)

    @property
    def names(self) -> list[str]:
        """Every node name (relative) the plan draws."""
        groups = (self.clouds, self.polylines, self.spheres, self.boxes, self.capsules)
        return [item.name for group in groups for item in group]


# ---- reading the result -------------------------------------------------------------------
def _points(value: Any, key: str, min_rows: int = 1) -> np.ndarray:
    """``value`` as finite ``(N, 3)`` floats; ValueError naming ``key`` otherwise."""
    try:
        p = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: expected a list of [x, y, z] points") from None
    if p.size == 0 and min_rows == 0:
        return p.reshape(0, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{key}: expected a list of [x, y, z] points, got shape "
                         f"{list(p.shape)}")
    if len(p) < min_rows:
        raise ValueError(f"{key}: needs at least {min_rows} points, got {len(p)}")
    if not np.all(np.isfinite(p)):
        raise ValueError(f"{key}: has a NaN or infinite entry")
    return p


def _joints(value: Any, key: str, model: RobotModel | None) -> np.ndarray:
    """``value`` as finite ``(S, dof)``; ValueError naming ``key`` otherwise."""
    try:
        q = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: expected a list of joint vectors") from None
    if q.ndim != 2 or len(q) == 0 or (model is not None and q.shape[1] != model.dof):
        want = f"(S, {model.dof})" if model is not None else "(S, dof)"
        raise ValueError(f"{key}: expected shape {want}, got {list(q.shape)}")
    if not np.all(np.isfinite(q)):
        raise ValueError(f"{key}: has a NaN or infinite entry")
    return q


def _times(value: Any, key: str, n: int) -> np.ndarray:
    t = np.asarray(value, dtype=float)
    if t.shape != (n,) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise ValueError(f"{key}: expected {n} non-decreasing times")
    return t - t[0]


def _uniform(n: int, seconds: float) -> np.ndarray:
    return np.linspace(0.0, seconds, n) if n > 1 else np.zeros(1)


def _motion(data: Any, key: str, model: RobotModel | None, *, t: Any = None,
            dt: float | None = None) -> Motion:
    """A motion from ``[[q...]]`` or ``{"t"?, "q"}``; without times: ``dt`` apart, else
    ``DEFAULT_SECONDS`` in total."""
    if isinstance(data, Mapping):
        if "q" not in data:
            raise ValueError(f"{key}.q: missing")
        t = data.get("t", t)
        q = _joints(data["q"], f"{key}.q", model)
        tkey = f"{key}.t"
    else:
        q = _joints(data, key, model)
        tkey = "t"
    if t is not None:
        times = _times(t, tkey, len(q))
    elif dt is not None:
        times = np.arange(len(q)) * dt
    else:
        times = _uniform(len(q), DEFAULT_SECONDS)
    return Motion(times, q)


def _fmt(v: Any, unit: str = "mm") -> str:
    try:
        return f"{float(v):,.0f} {unit}"
    except (TypeError, ValueError):
        return "?"


def _xyz(v: Any) -> str:
    try:
        return "[" + ", ".join(f"{float(x):,.0f}" for x in v) + "]"
    except (TypeError, ValueError):
        return "?"


ModelLookup = Callable[[str], RobotModel]


# ---- per kind -----------------------------------------------------------------------------
def _workspace(job: str, params: dict, result: dict, models: ModelLookup) -> Plan:
    points = _points(result.get("points"), "points", min_rows=0)
    robot = params.get("robot") or result.get("robot")
    lines = [f"**Workspace** of `{robot}` (job `{job}`): {len(points):,} of "
             f"{int(result.get('samples', len(points))):,} samples shown"]
    if "min" in result and "max" in result:
        lo, hi = result["min"], result["max"]
        for k, axis in enumerate("xyz"):
            lines.append(f"- {axis}: {_fmt(lo[k])} … {_fmt(hi[k])}")
    if "radial" in result:
        lines.append(f"- radial: {_fmt(result['radial'][0])} … {_fmt(result['radial'][1])}")
    if "vertical" in result:
        lines.append(f"- vertical: {_fmt(result['vertical'][0])} … "
                     f"{_fmt(result['vertical'][1])}")
    if "volume" in result:
        lines.append(f"- volume ≈ {float(result['volume']) * 1e-9:.3f} m³")
    return Plan(job, "workspace", robot=robot, clouds=(Cloud("points", points),),
                summary="\n".join(lines))


def _scene_items(scene: Any) -> tuple[list[Spheres], list[Box], list[Capsule]]:
    """Obstacles and bounds of a path-planning scene, parsed by ``planning.scene``."""
    from planning.scene import Scene

    def present(d: Any) -> Any:  # validated params carry every optional field as null
        return {k: v for k, v in d.items() if v is not None} if isinstance(d, Mapping) else d

    scene = present(scene)
    if isinstance(scene, dict) and isinstance(scene.get("obstacles"), list):
        scene["obstacles"] = [present(o) for o in scene["obstacles"]]
    try:
        parsed = Scene.from_dict(scene)
    except ValueError as exc:
        raise ValueError(f"params.scene: {exc}") from None
    spheres = [o for o in parsed.obstacles if o.kind == "sphere"]
    out_s = []
    if spheres:
        out_s.append(Spheres("obstacles", np.array([o.center for o in spheres]),
                             np.array([o.radius for o in spheres]), OBSTACLE_COLOR, 0.5))
    boxes = [Box("bounds", parsed.lower, parsed.upper, (150, 150, 150), wireframe=True)]
    boxes += [Box(f"obstacle_box_{k}", o.lower, o.upper, OBSTACLE_COLOR)
              for k, o in enumerate(parsed.obstacles) if o.kind == "box"]
    caps = [Capsule(f"obstacle_capsule_{k}", o.a, o.b, o.radius, OBSTACLE_COLOR)
            for k, o in enumerate(parsed.obstacles) if o.kind == "capsule"]
    return out_s, boxes, caps


def _arm_motion(params: dict, result: dict, models: ModelLookup) -> dict[str, Motion]:
    """The robot's motion of a path or sequence result, if it has one and names a robot."""
    robot = params.get("robot")
    def has(k: str) -> bool:
        data = result.get(k)
        rows = data.get("q") if isinstance(data, Mapping) else data
        return rows is not None and len(rows) > 0

    key = next((k for k in ("trajectory", "joint_path") if has(k)), None)
    if robot is None or key is None:
        return {}
    return {"": _motion(result[key], key, models(robot))}


def _path(job: str, params: dict, result: dict, models: ModelLookup) -> Plan:
    path = _points(result.get("path") or [], "path", min_rows=0)
    spheres, boxes, caps = ([], [], []) if "scene" not in params else \
        _scene_items(params["scene"])
    ends = [(k, c) for k, c in (("start", START_COLOR), ("goal", GOAL_COLOR))
            if params.get(k) is not None]
    extent = np.vstack([path] + [_points([params[k]], f"params.{k}") for k, _ in ends]
                       + [np.zeros((1, 3))])
    size = 0.01 * float(np.linalg.norm(np.ptp(extent, axis=0))) + 1.0
    for k, color in ends:
        spheres.append(Spheres(k, _points([params[k]], f"params.{k}"), np.array([size]), color))
    motions = _arm_motion(params, result, models)
    lines = [f"**Path** (job `{job}`, {params.get('algorithm', '?')}): {len(path)} points",
             f"- length: {_fmt(result.get('length'))}",
             f"- min clearance: {_fmt(result.get('min_clearance'))}"]
    if "runtime_s" in result:
        lines.append(f"- runtime: {float(result['runtime_s']):.2f} s")
    if result.get("success") is False:
        lines.append(f"- **no clear path**: {result.get('message', '')}")
    lines.append("- arm: moves along the joint path" if motions else
                 "- arm: no joint path in the result")
    polylines = (Polyline("path", path, PATH_COLOR),) if len(path) else ()
    return Plan(job, "path", robot=params.get("robot"), spheres=tuple(spheres),
                boxes=tuple(boxes), capsules=tuple(caps), polylines=polylines, motions=motions,
                summary="\n".join(lines))


def _ordered(holes: np.ndarray, order: Any, key: str, start: Any = None) -> np.ndarray:
    try:
        idx = np.asarray(order, dtype=int)
    except (TypeError, ValueError):
        raise ValueError(f"{key}: expected a list of hole indices") from None
    if idx.ndim != 1 or np.any(idx < 0) or np.any(idx >= len(holes)):
        raise ValueError(f"{key}: indices must lie in 0..{len(holes) - 1}")
    pts = holes[idx]
    if start is not None:
        pts = np.vstack([_points([start], "params.start"), pts])
    return pts


def _hole_size(holes: np.ndarray) -> float:
    span = float(np.linalg.norm(np.ptp(holes, axis=0))) if len(holes) > 1 else 0.0
    return max(span / 150.0, 5.0)


def _sequence(job: str, params: dict, result: dict, models: ModelLookup) -> Plan:
    holes = _points(params.get("holes"), "params.holes")
    line = _ordered(holes, result.get("order"), "order", params.get("start"))
    motions = _arm_motion(params, result, models)
    size = _hole_size(holes)
    lines = [f"**Drilling sequence** (job `{job}`, {params.get('algorithm', '?')}): "
             f"{len(holes)} holes", f"- length: {_fmt(result.get('length'))}"]
    if "runtime_s" in result:
        lines.append(f"- runtime: {float(result['runtime_s']):.2f} s")
    return Plan(job, "sequence", robot=params.get("robot"),
                spheres=(Spheres("holes", holes, np.full(len(holes), size), HOLE_COLOR),),
                polylines=(Polyline("order", line, PATH_COLOR),), motions=motions,
                summary="\n".join(lines))


def _multiarm(job: str, params: dict, result: dict, models: ModelLookup,
              rigs: Mapping[str, Any]) -> Plan:
    rig_id = params.get("rig")
    rig = rigs.get(rig_id) if rig_id is not None else None
    if rig is None:
        raise ValueError(f"params.rig: unknown rig {rig_id!r}")
    holes = params.get("holes") or {}
    per_arm = result.get("trajectories", result.get("arms", {}))
    if not isinstance(per_arm, Mapping):
        raise ValueError("trajectories: expected an object keyed by arm name")
    orders = result.get("orders", {}) if isinstance(result.get("orders"), Mapping) else {}
    spheres, polylines, motions = [], [], {}
    for arm, model in rig.arms.items():
        color = ARM_COLORS.get(arm, HOLE_COLOR)
        arm_holes = None
        if arm in holes and len(holes[arm]):
            arm_holes = _points(holes[arm], f"params.holes.{arm}")
            spheres.append(Spheres(f"{arm}/holes", arm_holes,
                                   np.full(len(arm_holes), _hole_size(arm_holes)), color))
        data = per_arm.get(arm)
        order = orders.get(arm)
        if isinstance(data, Mapping):
            order = data.get("order", order)
        if data is not None:
            motions[arm] = _motion(data, f"trajectories.{arm}", model, t=result.get("t"))
            tool = fk(model, motions[arm].q)[:, :3, 3]
            if len(tool) > 1:
                polylines.append(Polyline(f"{arm}/tool_path", tool, color))
        if arm_holes is not None and order is not None:
            polylines.append(Polyline(f"{arm}/order", _ordered(arm_holes, order,
                                                               f"orders.{arm}"), color))
    lines = [f"**Multi-arm plan** of `{rig_id}` (job `{job}`, "
             f"{params.get('planner', '?')}): arms {', '.join(motions) or 'without motion'}"]
    md = result.get("min_distance")
    if isinstance(md, Mapping):
        for pair, d in md.items():
            worst = min(d) if isinstance(d, list) and d else d
            lines.append(f"- min distance {pair}: {_fmt(worst)}")
    if "collisions" in result:
        c = result["collisions"]
        lines.append(f"- collisions: {len(c) if isinstance(c, list) else c}")
    return Plan(job, "multiarm", robot=rig_id, spheres=tuple(spheres),
                polylines=tuple(polylines), motions=motions, summary="\n".join(lines))


def _tracking(job: str, params: dict, result: dict, models: ModelLookup) -> Plan:
    robot = params.get("robot")
    if robot is None:
        raise ValueError("params.robot: missing")
    model = models(robot)
    dt = result.get("dt", params.get("dt", DEFAULT_TRACKING_DT))
    motion = _motion(result.get("q"), "q", model, t=result.get("t"), dt=float(dt))
    actual = fk(model, motion.q)[:, :3, 3]
    polylines = [Polyline("actual", actual, ACTUAL_COLOR)]
    desired_key = next((k for k in ("x_desired", "desired") if k in result), None)
    if desired_key is not None:
        polylines.insert(0, Polyline("desired", _points(result[desired_key], desired_key, 2),
                                     DESIRED_COLOR))
    lines = [f"**Tracking** of `{robot}` (job `{job}`): {len(motion.q)} samples, "
             f"{motion.duration:.1f} s",
             f"- mean error: {float(result.get('mean_error', math.nan)):.4g} mm, "
             f"max: {float(result.get('max_error', math.nan)):.4g} mm",
             "- blue: desired tool path, orange: actual" if desired_key else
             "- orange: actual tool path (the result carries no desired path)"]
    return Plan(job, "tracking", robot=robot, polylines=tuple(polylines),
                motions={"": motion}, summary="\n".join(lines))


def plan_from_result(kind: str, params: dict, result: Any, *, job: str = "",
                     models: ModelLookup, rigs: Mapping[str, Any] | None = None) -> Plan:
    """The ``Plan`` of a succeeded job of ``kind`` with ``params`` and ``result`` (JSON).

    ``models(id)`` resolves a robot id (``KeyError`` if unknown), ``rigs`` maps rig ids to
    ``kinematics.rigs.Rig``. ValueError for a kind the viewer cannot draw or a result without
    the documented shape (the message names the key).
    """
    if kind not in DRAWABLE_KINDS:
        raise ValueError(f"the viewer cannot show jobs of kind '{kind}'; it shows "
                         f"{', '.join(DRAWABLE_KINDS)}")
    if not isinstance(result, Mapping):
        raise ValueError("result: expected a JSON object")
    params = dict(params or {})

    def lookup(robot_id: str) -> RobotModel:
        try:
            return models(robot_id)
        except KeyError:
            raise ValueError(f"params.robot: unknown robot {robot_id!r}") from None

    if kind == "workspace":
        return _workspace(job, params, dict(result), lookup)
    if kind == "path":
        return _path(job, params, dict(result), lookup)
    if kind == "sequence":
        return _sequence(job, params, dict(result), lookup)
    if kind == "multiarm":
        return _multiarm(job, params, dict(result), lookup, rigs or {})
    return _tracking(job, params, dict(result), lookup)
