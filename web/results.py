"""A finished job's result turned into what the viewer draws: a ``Plan``.

Pure data: no scene node is made here (``web.scene.draw_plan`` draws a plan, ``web.site`` its
scene objects). Each job kind the viewer can show has a drawer here, registered with
``drawer(kind)``: the name must be a registered job kind (``app.jobs.catalog``) and may be
registered once; both are checked when this module is imported. A kind is drawable exactly
when it has a drawer (``drawable``).

``plan_from_result`` parses the job's params and result with the kind's own models
(``Params`` and ``Result``, the schemas ``GET /jobs/kinds`` publishes) and hands them, typed,
to the drawer; a result (or params) that does not match is a ``ValueError`` naming the key at
fault (``result.q.0: ...``), as is one the robot cannot follow (a joint vector of the wrong
length, a hole index out of range).

What each drawer reads, in mm, rad, s:

* ``workspace``: result ``points`` (a cloud coloured by height), with ``samples``, ``min``,
  ``max``, ``radial``, ``vertical``, ``volume`` for the summary; the robot is ``robot``.
* ``path``: params ``scene`` (obstacles and bounds), ``start``, ``goal``, ``robot``; result
  ``path``, ``length``, ``min_clearance``, ``runtime_s``, ``success``, ``message`` and, for a
  robot, ``trajectory {t, q}`` (the arm moves along it; without a trajectory, along
  ``joint_path`` in ``DEFAULT_SECONDS``).
* ``sequence``: params ``holes``, ``start``; result ``order`` (the drilling order drawn as a
  line through the holes), ``length``, ``runtime_s``. No robot moves.
* ``multiarm``: params ``rig``, ``planner``; result ``t`` and per arm ``arms[arm].holes`` (in
  drilling order) and ``arms[arm].q`` (the arm's motion), ``min_distance``, ``collisions``.
* ``tracking``: params ``robot``; result ``t``, ``q`` (the arm's motion), ``x_desired`` (the
  desired tool path), ``mean_error``, ``max_error``.
* ``motion``: params ``robot``, ``scene`` (its objects, inline since submission: drawn as a
  stored scene is), ``start`` and ``goal`` (or ``problems``); result ``joints`` (must be the
  robot's), and one problem's ``status``, ``path``, ``trajectory {t, q}``, ``goal``, ... (a
  batch: ``problems``, of which the first solved one is drawn, or the one ``problem``
  names). The arm moves along the trajectory; without one, along ``path`` at a constant
  joint speed in ``DEFAULT_SECONDS``. The tool's route (FK of the samples) is a polyline, the
  waypoints' tool points balls. ``plan_from_motion`` draws the answer of
  ``POST /robots/{id}/motion`` the same way (no scene: it carries none).
  A task (params ``steps``, result ``steps`` with each step's ``states``): the tool path of
  each line and arc step is a polyline of its own (``segments/<step index>``; its inner
  states get no waypoint ball), and ``Plan.task`` (``web.tasks.TaskTrack``) holds when each
  step plays, what it holds and the loads its attach steps take, which the viewer draws
  under ``loads/<id>`` and moves during playback.
* ``round``: params ``rig`` and the holes as the job reads them (``RoundParams.rig_holes``:
  ``holes`` or ``plan_iredes``, ``rig_pose`` applied); result ``booms.<boom>.t``, ``.q`` (each
  boom on the round's one clock, held at its last sample), ``holes[].boom``, ``start_s``,
  ``end_s`` (the holes, collar to toe, a ``TimedSegments`` recoloured as the round plays:
  planned, drilled, done) and ``unreachable``.
* ``pallet``: params ``robot``, ``pallet``, ``box``, ``grip_offset_mm``, ``dwell_s``,
  ``obstacles``; result ``boxes[]`` (``status``, ``q_pick``, ``q_place``, ``carry_s``,
  ``return_s``): no joint paths, so the arm moves straight in joint space from pick to place
  on the planned times, each placed box a load (``web.tasks``) on the tool during its carry
  and resting at the place from then on.
* ``piles``: params ``robot``, the plan (``PilesParams.pile_plan``), ``base_height``,
  ``carrier_radius``, ``carrier_start``, ``scene``; result ``piles[]`` (``setup``, ``order``,
  ``q``), ``setups[]`` (``x``, ``y``, ``heading``), ``unreached``: a static site map, the arm
  drawn (a line through its joints) at each set-up's first pile.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydantic import BaseModel, ValidationError

from app.api.schemas import MotionAnswerIn
from app.jobs.catalog import KINDS
from app.jobs.drilling_kinds import MultiarmParams, MultiarmResult, SequenceParams, SequenceResult
from app.jobs.kinds import WorkspaceParams, WorkspaceResult, error_text
from app.jobs.motion_kinds import MotionJobResult, MotionParams, collision_scene
from app.jobs.pallet_kinds import PalletJobResult, PalletParams
from app.jobs.path_kinds import PathParams, PathResult, SceneIn
from app.jobs.pile_kinds import PilesParams, PilesResult
from app.jobs.round_kinds import RoundParams, RoundResult
from app.jobs.tracking_kinds import TrackingParams, TrackingResult
from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.model import RobotModel
from planning.motion import PRISMATIC_SCALE

from .site import object_bounds_mm
from .tasks import (
    SEGMENT_COLOR,
    TOOL,
    Load,
    StepSpan,
    TaskTrack,
    state_times,
    step_tool_paths,
    task_track,
)
from .text import code, plain
from .timed import TimedSegments

__all__ = [
    "DRAWERS",
    "DEFAULT_SECONDS",
    "Motion",
    "Cloud",
    "Polyline",
    "Spheres",
    "Box",
    "Capsule",
    "Site",
    "TimedSegments",
    "Plan",
    "DrawContext",
    "drawer",
    "drawable",
    "picks_problems",
    "plan_from_result",
    "plan_from_motion",
    "MAX_TOOL_PATH_POINTS",
]

#: Playback length (s) of a joint path that carries no times.
DEFAULT_SECONDS = 5.0

PATH_COLOR = (20, 160, 60)
START_COLOR = (30, 120, 230)
GOAL_COLOR = (230, 50, 50)
OBSTACLE_COLOR = (200, 70, 70)
HOLE_COLOR = (250, 200, 30)
DESIRED_COLOR = (30, 120, 230)
ACTUAL_COLOR = (230, 80, 30)
ARM_COLORS = {"left": (30, 120, 230), "middle": (20, 160, 60), "right": (200, 60, 160)}
WAYPOINT_COLOR = (250, 200, 30)
#: Most tool points of a drawn joint path (FK of its samples, or of its waypoints refined).
MAX_TOOL_PATH_POINTS = 2000
#: Joint step (rad; mm / ``PRISMATIC_SCALE`` for prismatic joints) between the tool points
#: of a joint path drawn without a trajectory: its straight joint segments curve in space.
TOOL_PATH_STEP = 0.02


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
    #: Thickness relative to the plan's lines (``web.scene.draw_plan``).
    width: float = 1.0


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
class Site:
    """Scene objects (``planning.collision.shapes.SceneObject``, posed, mm) drawn as a stored
    scene is (``web.site``), under ``<plan root>/<name>/<object id>``."""

    name: str
    objects: tuple[Any, ...]


@dataclass(frozen=True)
class Plan:
    """What to draw for one job. ``robot``: robot or rig id to show with it (None: keep the
    current one); ``motions`` by arm (``""`` for a single robot, the arm name in a rig);
    ``summary`` Markdown for the GUI (text of the job's or the request's through
    ``web.text``). Node names are relative to the plan's root."""

    job: str
    kind: str
    robot: str | None = None
    clouds: tuple[Cloud, ...] = ()
    polylines: tuple[Polyline, ...] = ()
    spheres: tuple[Spheres, ...] = ()
    boxes: tuple[Box, ...] = ()
    capsules: tuple[Capsule, ...] = ()
    sites: tuple[Site, ...] = ()
    #: Segments recoloured with the plan's time (``web.timed``): a round's holes.
    timed: tuple[TimedSegments, ...] = ()
    motions: dict[str, Motion] = field(default_factory=dict)
    summary: str = ""
    #: A task's steps as played and the loads it carries (``web.tasks``); None otherwise.
    task: TaskTrack | None = None

    @property
    def duration(self) -> float:
        return max((m.duration for m in self.motions.values()), default=0.0)

    @property
    def names(self) -> list[str]:
        """Every node name (relative) the plan draws."""
        groups = (self.clouds, self.polylines, self.spheres, self.boxes, self.capsules,
                  self.sites, self.timed)
        return [item.name for group in groups for item in group]

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """World bounds ``(lower (3,), upper (3,))`` mm of what the plan draws (its arms'
        motions not included); None when it draws nothing."""
        lows, highs = [], []

        def add(lo, hi) -> None:
            lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
            if lo.size and np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)):
                lows.append(lo)
                highs.append(hi)

        for group in (self.clouds, self.polylines):
            for item in group:
                P = np.asarray(item.points, dtype=float).reshape(-1, 3)
                if len(P):
                    add(P.min(axis=0), P.max(axis=0))
        for item in self.timed:
            P = np.asarray(item.points, dtype=float).reshape(-1, 3)
            if len(P):
                add(P.min(axis=0), P.max(axis=0))
        for s in self.spheres:
            C = np.asarray(s.centers, dtype=float).reshape(-1, 3)
            if len(C):
                r = np.asarray(s.radii, dtype=float).reshape(-1, 1)
                add((C - r).min(axis=0), (C + r).max(axis=0))
        for b in self.boxes:
            add(b.lower, b.upper)
        for c in self.capsules:
            ends = np.array([c.a, c.b], dtype=float)
            add(ends.min(axis=0) - c.radius, ends.max(axis=0) + c.radius)
        for site in self.sites:
            for o in site.objects:
                found = object_bounds_mm(o)
                if found is not None:
                    add(*found)
        if not lows:
            return None
        return np.min(lows, axis=0), np.max(highs, axis=0)


# ---- drawers ------------------------------------------------------------------------------
ModelLookup = Callable[[str], RobotModel]


@dataclass(frozen=True)
class DrawContext:
    """What a drawer may look up: the job id, robot models by id (``ValueError`` naming
    ``params.robot`` if unknown) and rigs by id (``kinematics.rigs.Rig``); ``problem``: the
    problem of a batch to draw (kinds registered with ``problems=True``; None: the drawer's
    choice)."""

    job: str
    models: ModelLookup
    rigs: Mapping[str, Any]
    problem: int | None = None


Drawer = Callable[[Any, Any, DrawContext], "Plan"]

#: The drawer of each drawable job kind.
DRAWERS: dict[str, Drawer] = {}
#: The kinds whose jobs may hold a batch of problems, one of which is drawn.
_PROBLEM_KINDS: set[str] = set()


def drawer(kind: str, *, problems: bool = False) -> Callable[[Drawer], Drawer]:
    """Register the decorated function as the drawer of job kind ``kind``: it gets the
    job's params and result as the kind's models and a ``DrawContext``, and returns the
    ``Plan``. ``problems``: the kind's jobs may be batches, and the drawer draws the one
    ``DrawContext.problem`` names. ValueError (at import) if ``kind`` is not a job kind or has
    a drawer already."""

    def add(fn: Drawer) -> Drawer:
        if kind not in KINDS:
            raise ValueError(f"drawer {fn.__name__}: {kind!r} is not a job kind (known: "
                             f"{', '.join(sorted(KINDS))})")
        if kind in DRAWERS:
            raise ValueError(f"job kind {kind!r} has a drawer already "
                             f"({DRAWERS[kind].__name__})")
        DRAWERS[kind] = fn
        if problems:
            _PROBLEM_KINDS.add(kind)
        return fn

    return add


def drawable(kind: str) -> bool:
    """Whether the viewer can draw jobs of ``kind``."""
    return kind in DRAWERS


def picks_problems(kind: str) -> bool:
    """Whether a job of ``kind`` may be drawn one problem of its batch at a time."""
    return kind in _PROBLEM_KINDS


# ---- checks the models cannot make --------------------------------------------------------
def _points(value: Any) -> np.ndarray:
    """``value`` (a typed list of [x, y, z]) as ``(N, 3)`` floats."""
    return np.asarray(value, dtype=float).reshape(-1, 3)


def _joints(value: Any, key: str, model: RobotModel) -> np.ndarray:
    """``value`` as ``(S, dof)`` of ``model``; ValueError naming ``key`` otherwise."""
    rows = list(value)
    if not rows or any(len(row) != model.dof for row in rows):
        got = sorted({len(row) for row in rows})
        raise ValueError(f"{key}: expected {model.dof} joint values per row for robot "
                         f"'{model.id}', got {got or 'no rows'}")
    return np.asarray(rows, dtype=float)


def _times(value: Any, key: str, n: int) -> np.ndarray:
    t = np.asarray(value, dtype=float)
    if t.shape != (n,) or np.any(np.diff(t) < 0):
        raise ValueError(f"{key}: expected {n} non-decreasing times, got {len(t)}")
    return t - t[0]


def _motion(q: Any, key: str, model: RobotModel, t: Any = None, tkey: str = "t") -> Motion:
    """A motion through the rows of ``q``, at times ``t`` (from 0), else uniformly over
    ``DEFAULT_SECONDS``."""
    rows = _joints(q, key, model)
    if t is not None:
        times = _times(t, tkey, len(rows))
    else:
        times = np.linspace(0.0, DEFAULT_SECONDS, len(rows)) if len(rows) > 1 else np.zeros(1)
    return Motion(times, rows)


def _fmt(v: float | None, unit: str = "mm") -> str:
    return "?" if v is None else f"{float(v):,.0f} {unit}"


def _hole_size(holes: np.ndarray) -> float:
    span = float(np.linalg.norm(np.ptp(holes, axis=0))) if len(holes) > 1 else 0.0
    return max(span / 150.0, 5.0)


# ---- per kind -----------------------------------------------------------------------------
@drawer("workspace")
def _workspace(params: WorkspaceParams, result: WorkspaceResult, ctx: DrawContext) -> Plan:
    points = _points(result.points)
    lines = [f"**Workspace** of {code(result.robot)} (job {code(ctx.job)}): {len(points):,} of "
             f"{result.samples:,} samples shown"]
    for k, axis in enumerate("xyz"):
        lines.append(f"- {axis}: {_fmt(result.min[k])} … {_fmt(result.max[k])}")
    lines.append(f"- radial: {_fmt(result.radial[0])} … {_fmt(result.radial[1])}")
    lines.append(f"- vertical: {_fmt(result.vertical[0])} … {_fmt(result.vertical[1])}")
    lines.append(f"- volume ≈ {result.volume * 1e-9:.3f} m³")
    return Plan(ctx.job, "workspace", robot=result.robot, clouds=(Cloud("points", points),),
                summary="\n".join(lines))


def _scene_items(scene: SceneIn) -> tuple[list[Spheres], list[Box], list[Capsule]]:
    """Obstacles and bounds of a path-planning scene."""
    try:
        parsed = scene.to_scene()
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


@drawer("path")
def _path(params: PathParams, result: PathResult, ctx: DrawContext) -> Plan:
    path = _points(result.path)
    spheres, boxes, caps = _scene_items(params.scene)
    # A robot path may give joint values (arm.q_start, arm.q_goal) instead of points.
    ends = [(name, point if point is not None else (path[k] if len(path) else None), color)
            for name, point, k, color in (("start", params.start, 0, START_COLOR),
                                          ("goal", params.goal, -1, GOAL_COLOR))]
    ends = [e for e in ends if e[1] is not None]
    extent = np.vstack([path] + [np.reshape(e[1], (1, 3)) for e in ends])
    size = 0.01 * float(np.linalg.norm(np.ptp(extent, axis=0))) + 1.0 if len(extent) else 1.0
    for name, point, color in ends:
        spheres.append(Spheres(name, _points([point]), np.array([size]),
                               color))
    motions: dict[str, Motion] = {}
    if params.robot is not None:
        model = ctx.models(params.robot)
        if result.trajectory is not None and result.trajectory.q:
            motions[""] = _motion(result.trajectory.q, "result.trajectory.q", model,
                                  result.trajectory.t, "result.trajectory.t")
        elif result.joint_path:
            motions[""] = _motion(result.joint_path, "result.joint_path", model)
    planner = f", {plain(result.planner.replace('_', ' '))}" if result.planner else ""
    lines = [f"**Path** (job {code(ctx.job)}, {plain(params.algorithm)}{planner}): "
             f"{len(path)} points",
             f"- length: {_fmt(result.length)}",
             f"- min clearance: {_fmt(result.min_clearance)}",
             f"- runtime: {result.runtime_s:.2f} s"]
    if not result.success:
        lines.append(f"- **no clear path**: {plain(result.message)}")
    lines.append("- arm: moves along the joint path" if motions else
                 "- arm: no joint path in the result")
    polylines = (Polyline("path", path, PATH_COLOR),) if len(path) else ()
    return Plan(ctx.job, "path", robot=params.robot, spheres=tuple(spheres),
                boxes=tuple(boxes), capsules=tuple(caps), polylines=polylines, motions=motions,
                summary="\n".join(lines))


@drawer("sequence")
def _sequence(params: SequenceParams, result: SequenceResult, ctx: DrawContext) -> Plan:
    holes = _points(params.holes)
    order = np.asarray(result.order, dtype=int)
    if len(order) and (order.min() < 0 or order.max() >= len(holes)):
        raise ValueError(f"result.order: hole indices must lie in 0..{len(holes) - 1}")
    line = holes[order]
    if params.start is not None:
        line = np.vstack([[params.start], line])
    lines = [f"**Drilling sequence** (job {code(ctx.job)}, {plain(result.algorithm)}): "
             f"{len(holes)} holes", f"- length: {_fmt(result.length)}",
             f"- runtime: {result.runtime_s:.2f} s"]
    return Plan(ctx.job, "sequence", spheres=(
        Spheres("holes", holes, np.full(len(holes), _hole_size(holes)), HOLE_COLOR),),
        polylines=(Polyline("order", line, PATH_COLOR),), summary="\n".join(lines))


@drawer("multiarm")
def _multiarm(params: MultiarmParams, result: MultiarmResult, ctx: DrawContext) -> Plan:
    rig = ctx.rigs.get(params.rig)
    if rig is None:
        raise ValueError(f"params.rig: unknown rig {params.rig!r}")
    for arm in result.arms:
        if arm not in rig.arms:
            raise ValueError(f"result.arms.{arm}: rig {params.rig!r} has no arm {arm!r}")
    spheres, polylines, motions = [], [], {}
    for arm, model in rig.arms.items():
        data = result.arms.get(arm)
        if data is None:
            continue
        color = ARM_COLORS.get(arm, HOLE_COLOR)
        motions[arm] = _motion(data.q, f"result.arms.{arm}.q", model, result.t, "result.t")
        tool = fk(model, motions[arm].q)[:, :3, 3]
        if len(tool) > 1:
            polylines.append(Polyline(f"{arm}/tool_path", tool, color))
        holes = _points(data.holes)
        if len(holes):
            spheres.append(Spheres(f"{arm}/holes", holes,
                                   np.full(len(holes), _hole_size(holes)), color))
            polylines.append(Polyline(f"{arm}/order", holes, color))
    lines = [f"**Multi-arm plan** of {code(params.rig)} (job {code(ctx.job)}, "
             f"{plain(result.planner)}): arms "
             f"{', '.join(plain(arm) for arm in motions) or 'without motion'}"]
    for pair, d in result.min_distance.items():
        lines.append(f"- min distance {plain(pair)}: {_fmt(min(d) if d else None)}")
    lines.append(f"- collisions: {result.collisions}")
    if not result.success:
        lines += [f"- **{plain(m)}**" for m in result.messages]
    return Plan(ctx.job, "multiarm", robot=params.rig, spheres=tuple(spheres),
                polylines=tuple(polylines), motions=motions, summary="\n".join(lines))


@drawer("tracking")
def _tracking(params: TrackingParams, result: TrackingResult, ctx: DrawContext) -> Plan:
    model = ctx.models(params.robot)
    motion = _motion(result.q, "result.q", model, result.t, "result.t")
    desired = _points(result.x_desired)
    if len(desired) != len(motion.q):
        raise ValueError(f"result.x_desired: expected {len(motion.q)} points (one per step), "
                         f"got {len(desired)}")
    actual = fk(model, motion.q)[:, :3, 3]
    lines = [f"**Tracking** of {code(params.robot)} (job {code(ctx.job)}): {len(motion.q)} "
             f"samples, {motion.duration:.1f} s",
             f"- mean error: {result.mean_error:.4g} mm, max: {result.max_error:.4g} mm",
             "- blue: desired tool path, orange: actual"]
    return Plan(ctx.job, "tracking", robot=params.robot,
                polylines=(Polyline("desired", desired, DESIRED_COLOR),
                           Polyline("actual", actual, ACTUAL_COLOR)),
                motions={"": motion}, summary="\n".join(lines))


# ---- motion -----------------------------------------------------------------------------
def _metric_weights(model: RobotModel) -> np.ndarray:
    """The planner's joint-space metric per joint ``(dof,)``: 1 per rad, 1 per
    ``PRISMATIC_SCALE`` mm."""
    return np.array([1.0 if j.revolute else 1.0 / PRISMATIC_SCALE for j in model.joints])


def _refined(path: np.ndarray, weights: np.ndarray, step: float = TOOL_PATH_STEP
             ) -> np.ndarray:
    """The joint path ``(K, dof)`` with states inserted along its straight segments, at most
    ``step`` apart on every joint (weighted), within ``MAX_TOOL_PATH_POINTS`` or so."""
    if len(path) < 2:
        return path
    span = (np.abs(np.diff(path, axis=0)) * weights).max(axis=1)  # (K-1,)
    counts = np.maximum(1, np.ceil(span / step)).astype(int)
    if counts.sum() >= MAX_TOOL_PATH_POINTS:
        counts = np.maximum(1, counts * (MAX_TOOL_PATH_POINTS - 1) // counts.sum())
    seg = np.repeat(np.arange(len(counts)), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    frac = (np.arange(counts.sum()) - first + 1) / np.repeat(counts, counts)
    inner = path[seg] + (path[seg + 1] - path[seg]) * frac[:, None]
    return np.vstack([path[:1], inner])


def _constant_speed(path: np.ndarray, weights: np.ndarray) -> Motion:
    """A motion along the waypoints ``(K, dof)`` at a constant joint speed (the planner's
    metric) over ``DEFAULT_SECONDS``."""
    steps = np.linalg.norm(np.diff(path, axis=0) * weights, axis=1)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    if s[-1] <= 0.0:
        return Motion(np.linspace(0.0, DEFAULT_SECONDS, len(path)), path)
    return Motion(DEFAULT_SECONDS * s / s[-1], path)


def _pick_problem(problems: list[Any], wanted: int | None) -> int:
    """The index of the problem to draw: ``wanted``, else the first solved one (else 0)."""
    n = len(problems)
    if wanted is None:
        return next((i for i, p in enumerate(problems) if p.status == "ok"), 0)
    if not 0 <= wanted < n:
        raise FieldError(("problem",), f"the job planned {n} problem(s), numbered 0 to "
                         f"{n - 1}; got {wanted}")
    return wanted


def _motion_site(scene: Any) -> tuple[tuple[Site, ...], str]:
    """The scene a motion job planned in (its params' ``scene``) as plan items, and its line
    of the summary."""
    if scene is None:
        return (), "none (self-collision only)"
    if isinstance(scene, str):  # a worker refuses these: only a job never submitted has one
        return (), f"stored scene {code(scene)}, not filled in (not drawn)"
    try:
        objects = collision_scene(scene).objects
    except FieldError as exc:
        where = ".".join(str(k) for k in exc.loc)
        raise ValueError(f"params.{where}: {exc.message}") from None
    text = f"{len(objects)} object(s)"
    if isinstance(scene.get("id"), str):
        text += f" of stored scene {code(scene['id'])}, as it was when the job was submitted"
    return ((Site("scene", tuple(objects)),) if objects else ()), text


def _motion_plan(model: RobotModel, one: Any, key: str, *, job: str, head: str,
                 start: Any = None, goal: Any = None, asked: str = "params",
                 site: tuple[Site, ...] = (), notes: tuple[str, ...] = (),
                 steps: Any = None) -> Plan:
    """The plan of one motion problem's outcome ``one`` (a ``MotionOut``: ``status``,
    ``path``, ``trajectory``, ``goal``, ...; ``key`` names it in errors) for ``model``.
    ``start (dof,)`` and ``goal`` (a ``GoalIn``) are the problem's (``asked`` names them),
    when known: the arm waits at the start of an unsolved problem, and the goal ball marks
    the goal asked for. ``steps``: a task's steps as asked (the job's ``params.steps``),
    read with the result's ``steps``: the tool path of each line and arc, the step played
    and the loads carried (``web.tasks``)."""
    weights = _metric_weights(model)
    path = _joints(one.path, f"{key}.path", model) if one.path else np.zeros((0, model.dof))
    trajectory = one.trajectory
    if trajectory is not None and trajectory.q:
        motion = _motion(trajectory.q, f"{key}.trajectory.q", model, trajectory.t,
                         f"{key}.trajectory.t")
        timing = f"{motion.duration:.2f} s along the time-optimal trajectory"
        stride = max(1, -(-len(motion.q) // MAX_TOOL_PATH_POINTS))
        samples = np.vstack([motion.q[:-1:stride], motion.q[-1:]])
    elif len(path) >= 2:
        motion = _constant_speed(path, weights)
        timing = (f"{DEFAULT_SECONDS:g} s at a constant joint speed (the result has no "
                  "trajectory)")
        samples = _refined(path, weights)
    else:
        motion, samples, timing = None, np.zeros((0, model.dof)), ""
    q_start = path[0] if len(path) else (
        None if start is None else _joints([start], f"{asked}.start", model)[0])
    if motion is None and q_start is not None:
        motion = Motion(np.zeros(1), q_start[None, :])  # the arm waits at the start
    q_goal = None
    if one.goal is not None:
        q_goal = _joints([one.goal], f"{key}.goal", model)[0]
    elif goal is not None and goal.q is not None:
        q_goal = _joints([goal.q], f"{asked}.goal.q", model)[0]
    ends = []
    if q_start is not None:
        ends.append(("start", fk(model, q_start)[:3, 3], START_COLOR))
    if q_goal is not None:
        ends.append(("goal", fk(model, q_goal)[:3, 3], GOAL_COLOR))
    elif goal is not None and goal.pose is not None:
        ends.append(("goal", np.asarray(goal.pose, dtype=float)[:3, 3], GOAL_COLOR))
    tool = fk(model, samples)[:, :3, 3] if len(samples) else np.zeros((0, 3))
    marks = fk(model, path)[:, :3, 3] if len(path) else np.zeros((0, 3))
    extent = np.vstack([tool, marks, *[[p] for _, p, _ in ends]])
    size = max(0.01 * float(np.linalg.norm(np.ptp(extent, axis=0))), 5.0) \
        if len(extent) else 5.0
    polylines = (Polyline("tool_path", tool, PATH_COLOR),) if len(tool) > 1 else ()
    track = None
    done = getattr(one, "steps", None)
    if steps is not None and done and motion is not None and len(path):
        times = state_times(path, motion.t, motion.q, weights)
        track = task_track(model, steps, done, path, times, key=f"{asked}.steps")
        segments = step_tool_paths(model, path, done)   # states checked by task_track
        polylines += tuple(Polyline(f"segments/{i}", points, SEGMENT_COLOR, width=1.5)
                           for i, points in segments.items())
        # A line's or an arc's states are its own polyline: balls only where steps meet.
        inner = np.zeros(len(path), dtype=bool)
        for s in done:
            if s.index in segments:
                inner[s.states[0] + 1:s.states[1]] = True
        marks = marks[~inner]
    spheres = [Spheres("waypoints", marks, np.full(len(marks), 0.6 * size), WAYPOINT_COLOR)] \
        if len(marks) else []
    spheres += [Spheres(name, _points([p]), np.array([size]), color)
                for name, p, color in ends]
    lines = [head]
    lines += list(notes)
    if one.status == "ok":
        length = "?" if one.length is None else f"{one.length:.3f}"
        lines.append(f"- path: {len(path)} waypoints, joint-space length {length}")
        if timing:
            lines.append(f"- arm: {timing}")
        clearance = "?" if one.min_clearance is None else f"{one.min_clearance:.1f} mm"
        took = "?" if one.planning_time_s is None else f"{one.planning_time_s:.3f} s"
        lines.append(f"- planning: {took}, min clearance {clearance}")
    else:
        lines.append(f"- **{plain(one.status.replace('_', ' '))}**: {plain(one.message)}")
        if one.pairs:
            lines.append("- colliding: " + ", ".join(f"{code(a)}–{code(b)}"
                                                     for a, b in one.pairs))
        if q_start is not None:
            lines.append("- arm: at the start")
    legend = "- green: the tool's route, yellow: waypoints, blue: start, red: goal"
    if track is not None:
        lines.append(f"- task: {len(track.spans)} of {track.total} steps planned, "
                     f"{len(track.loads)} load(s)")
        legend += ", magenta: lines and arcs, brown: loads"
    lines.append(legend)
    return Plan(job, "motion", robot=model.id, polylines=polylines, spheres=tuple(spheres),
                sites=site, motions={"": motion} if motion is not None else {},
                summary="\n".join(lines), task=track)


def _check_joints(joints: list[str], model: RobotModel, key: str) -> None:
    names = [j.name for j in model.joints]
    if list(joints) != names:
        raise ValueError(f"{key}: the result's joints {list(joints)} are not those of robot "
                         f"'{model.id}' ({names}); was the robot replaced?")


@drawer("motion", problems=True)
def _motion_job(params: MotionParams, result: MotionJobResult, ctx: DrawContext) -> Plan:
    model = ctx.models(params.robot)
    _check_joints(result.joints, model, "result.joints")
    notes = []
    if result.problems is None:
        if ctx.problem not in (None, 0):
            raise FieldError(("problem",), f"job {ctx.job} planned one problem (number 0), "
                             f"not a batch; got {ctx.problem}")
        one, key, start, goal = result, "result", params.start, params.goal
        asked_key = "params"
    else:
        asked = params.problems or []
        if len(asked) != len(result.problems):
            raise ValueError(f"result.problems: expected {len(asked)} results (one per "
                             f"problem), got {len(result.problems)}")
        index = _pick_problem(result.problems, ctx.problem)
        one, key = result.problems[index], f"result.problems.{index}"
        start, goal = asked[index].start, asked[index].goal
        asked_key = f"params.problems.{index}"
        notes.append(f"- problem {index} of 0..{len(asked) - 1} ({result.summary.solved} of "
                     f"{len(asked)} solved; `\"problem\": k` in `POST /viewer/show` picks "
                     "another)")
    site, scene_text = _motion_site(params.scene)
    notes.append(f"- scene: {scene_text}")
    head = (f"**Motion** of {code(model.id)} (job {code(ctx.job)}, {plain(one.planner)}): "
            f"**{plain(one.status)}**")
    steps = params.steps if result.problems is None else None
    return _motion_plan(model, one, key, job=ctx.job, head=head, start=start, goal=goal,
                        asked=asked_key, site=site, notes=tuple(notes), steps=steps)


def plan_from_motion(answer: Any, *, models: ModelLookup) -> Plan:
    """The ``Plan`` of an answer of ``POST /robots/{id}/motion`` (its JSON object as returned,
    or ``app.api.schemas.MotionAnswerIn``): the robot moves along it as along a motion job's
    result. The answer carries no scene (show the stored scene it was planned in alongside).
    ValueError naming the key (``motion.path``) for an answer of another shape or robot;
    ``motion.robot`` if unknown."""
    typed = _parse(MotionAnswerIn, answer, "motion")
    try:
        model = models(typed.robot)
    except KeyError:
        raise ValueError(f"motion.robot: unknown robot {typed.robot!r}") from None
    _check_joints(typed.joints, model, "motion.joints")
    head = (f"**Motion** of {code(model.id)} (answer of {code(f'POST /robots/{model.id}/motion')}"
            f", {plain(typed.planner)}): **{plain(typed.status)}**")
    return _motion_plan(model, typed, "motion", job="", head=head)


# ---- work cycles: round, pallet, piles ---------------------------------------------------
#: A round's hole before its boom starts it, and one no boom can drill.
HOLE_PLANNED_COLOR = (165, 165, 165)
HOLE_UNREACHABLE_COLOR = (220, 40, 40)
#: A drilled hole's colour: its boom's, this much of it.
HOLE_DONE_SHADE = 0.35
#: Colours of the set-ups of a pile plan, in turn.
SETUP_COLORS = ((30, 120, 230), (230, 120, 20), (20, 160, 60), (200, 60, 160),
                (120, 80, 200), (0, 170, 170), (180, 150, 20), (120, 120, 120))
#: Length (mm) of the stroke drawn along a pile's axis from its head.
PILE_STROKE_MM = 1500.0
PALLET_COLOR = (150, 110, 60)


def _bright(color: tuple[int, int, int]) -> tuple[int, int, int]:
    """``color`` at full brightness (its largest channel 255): a hole being drilled."""
    top = max(max(color), 1)
    return tuple(int(round(c * 255 / top)) for c in color)  # type: ignore[return-value]


def _dark(color: tuple[int, int, int]) -> tuple[int, int, int]:
    return tuple(int(HOLE_DONE_SHADE * c) for c in color)  # type: ignore[return-value]


def _timed_motion(q: Any, key: str, model: RobotModel, t: Any, tkey: str) -> Motion:
    """A motion on the job's own clock: times ``t`` as given (>= 0, non-decreasing; not
    shifted to start at 0, so several arms and the holes keep one clock)."""
    rows = _joints(q, key, model)
    times = np.asarray(t, dtype=float)
    if times.shape != (len(rows),) or np.any(np.diff(times) < 0) or \
            (len(times) and times[0] < 0):
        raise ValueError(f"{tkey}: expected {len(rows)} non-decreasing times from 0 or "
                         f"later, got {len(times)}")
    return Motion(times, rows)


@drawer("round")
def _round(params: RoundParams, result: RoundResult, ctx: DrawContext) -> Plan:
    """Every boom on its own times (held at its last sample once done), the holes collar to
    toe recoloured as the round plays: grey planned, the boom's colour lightened while it
    drills, darkened once done; red: no boom can drill it."""
    rig = ctx.rigs.get(params.rig)
    if rig is None:
        raise ValueError(f"params.rig: unknown rig {params.rig!r}")
    motions: dict[str, Motion] = {}
    polylines = []
    colors = {a: ARM_COLORS.get(a, SETUP_COLORS[k % len(SETUP_COLORS)])
              for k, a in enumerate(rig.arms)}
    for boom, data in result.booms.items():
        if boom not in rig.arms:
            raise ValueError(f"result.booms.{boom}: rig {params.rig!r} has no boom {boom!r}")
        model = rig.arms[boom]
        motions[boom] = _timed_motion(data.q, f"result.booms.{boom}.q", model, data.t,
                                      f"result.booms.{boom}.t")
        tool = fk(model, motions[boom].q)[:, :3, 3]
        if len(tool) > 1:
            polylines.append(Polyline(f"{boom}/tool_path", tool, colors[boom], width=0.5))
    # The holes as the job reads them: params.holes or the IREDES plan, rig_pose applied.
    C, D, ids, _ = params.rig_holes()
    where = {h: k for k, h in enumerate(ids)}
    K = len(ids)
    times = np.full((K, 2), np.inf)
    palette = np.empty((K, 3, 3))
    palette[:] = HOLE_PLANNED_COLOR
    drilled = np.zeros(K, dtype=bool)
    for j, h in enumerate(result.holes):
        k = where.get(h.id)
        if k is None:
            raise ValueError(f"result.holes.{j}.id: the plan has no hole {h.id!r}")
        if h.boom not in colors:
            raise ValueError(f"result.holes.{j}.boom: rig {params.rig!r} has no boom "
                             f"{h.boom!r}")
        if not h.start_s <= h.end_s:
            raise ValueError(f"result.holes.{j}.end_s: ends before it starts")
        times[k] = (h.start_s, h.end_s)
        palette[k, 1], palette[k, 2] = _bright(colors[h.boom]), _dark(colors[h.boom])
        drilled[k] = True
    unreachable = [where[u.id] for u in result.unreachable if u.id in where]
    palette[unreachable] = HOLE_UNREACHABLE_COLOR
    holes = TimedSegments("holes", np.stack([C, D], axis=1), times, palette, width=2.0)
    lines = [f"**Drilling round** of {code(params.rig)} (job {code(ctx.job)}): "
             f"{int(drilled.sum())} of {K} holes drilled by "
             f"{', '.join(plain(b) for b in motions) or 'no boom'}",
             f"- cycle time: {result.cycle_time_s:,.0f} s (lower bound "
             f"{result.lower_bound_s:,.0f} s)"]
    for boom, data in result.booms.items():
        lines.append(f"- {plain(boom)}: {len(data.holes)} holes, done at {data.end_s:,.0f} s, "
                     f"waited {data.wait_s:,.0f} s")
    if result.min_boom_clearance_mm is not None:
        lines.append(f"- least boom clearance: {_fmt(result.min_boom_clearance_mm)}"
                     + (f" ({plain(result.clearance_pair)})" if result.clearance_pair else ""))
    if result.unreachable:
        lines.append(f"- **{len(result.unreachable)} hole(s) no boom can drill** (red)")
    lines.append("- holes collar to toe: grey planned, the boom's colour (bright) while "
                 "drilled, dark once done; each boom holds its last pose when done")
    return Plan(ctx.job, "round", robot=params.rig, polylines=tuple(polylines),
                timed=(holes,), motions=motions, summary="\n".join(lines))


def _keyframes(frames: list[tuple[float, np.ndarray]]) -> Motion:
    """A motion through ``(time, q)`` key frames (non-decreasing times); of frames at one
    time the last is kept."""
    t = np.array([f[0] for f in frames], dtype=float)
    keep = np.append(np.diff(t) > 1e-12, True)
    return Motion(t[keep], np.array([f[1] for f in frames], dtype=float)[keep])


@drawer("pallet")
def _pallet(params: PalletParams, result: PalletJobResult, ctx: DrawContext) -> Plan:
    """The pallet, its obstacles and the boxes: each placed box is taken at its pick, rides
    on the tool during its carry and rests where it was placed from its place time on. The
    result holds each box's pick and place configurations and durations, not the joint paths:
    the arm moves straight in joint space between them (said in the panel)."""
    from planning.cycles.pallet import grasp_transform
    from planning.geometry.objects import parse_object, parse_objects

    model = ctx.models(params.robot)
    _check_joints(result.joints, model, "result.joints")
    pallet, box = params.objects()
    G = grasp_transform(box, params.grip_offset_mm)
    dwell = params.dwell_s
    frames: list[tuple[float, np.ndarray]] = []
    loads: list[Load] = []
    spans: list[StepSpan] = []
    clock = 0.0
    placed = [b for b in result.boxes if b.status == "placed"]
    for b in placed:
        key = f"result.boxes.{b.index}"
        if b.q_pick is None or b.q_place is None:
            raise ValueError(f"{key}: a placed box needs q_pick and q_place")
        q_pick = _joints([b.q_pick], f"{key}.q_pick", model)[0]
        q_place = _joints([b.q_place], f"{key}.q_place", model)[0]
        pick_t = clock
        place_t = pick_t + dwell + b.carry_s
        frames += [(pick_t, q_pick), (pick_t + dwell, q_pick), (place_t, q_place),
                   (place_t + dwell, q_place)]
        name = f"box{b.index}"
        shape = parse_object({"type": "box", "id": name, "size": list(result.box_size),
                              "pose": G.tolist()}, 0)
        loads.append(Load(name, name, shape, TOOL, pick_t, q_pick, detach_time=place_t,
                          detach_q=q_place, placed=True, shown_from=pick_t, step=b.index))
        spans.append(StepSpan(b.index, "carry", pick_t, place_t,
                              f"box {b.index} (layer {b.layer}): carried, {b.carry_s:.1f} s"))
        spans.append(StepSpan(b.index, "return", place_t, place_t + dwell + b.return_s,
                              f"box {b.index} placed; back to the pick, {b.return_s:.1f} s"))
        clock = place_t + dwell + b.return_s
    motions = {"": _keyframes(frames)} if frames else {}
    sites = [Site("pallet", (parse_object(pallet.object(), 0),))]
    if params.obstacles:
        sites.append(Site("obstacles", tuple(parse_objects(list(params.obstacles)))))
    lines = [f"**Pallet** of {code(model.id)} (job {code(ctx.job)}, {plain(result.pattern)}):"
             f" {result.placed} of {result.total} boxes placed",
             f"- cycle: {result.pallet_s:,.1f} s, {result.boxes_per_hour:,.0f} boxes/h",
             f"- per layer: {', '.join(str(n) for n in result.per_layer)} boxes"]
    missed = [b for b in result.boxes if b.status != "placed"]
    if missed:
        lines.append("- not placed: " + ", ".join(
            f"box {b.index} ({plain(b.status.replace('_', ' '))})" for b in missed[:8])
            + (" …" if len(missed) > 8 else ""))
    lines.append("- the result holds each box's pick and place configurations, not the "
                 "planned paths: the arm moves **straight in joint space** between them "
                 "(the planned carry goes around the boxes placed), on the planned times")
    lines.append("- brown: a box, on the tool while carried, where it rests once placed")
    track = TaskTrack(len(spans), tuple(spans), tuple(loads)) if loads else None
    return Plan(ctx.job, "pallet", robot=model.id, sites=tuple(sites), motions=motions,
                summary="\n".join(lines), task=track)


@drawer("piles")
def _piles(params: PilesParams, result: PilesResult, ctx: DrawContext) -> Plan:
    """The site: each pile a stroke down its axis from its head, coloured by its set-up (red:
    unreached); per set-up (``setups/<k>``) the carrier (a post from the ground to the arm's
    base), the piles' heads and the arm at its first pile (a line through its joints, site
    frame); the carrier's route between set-ups."""
    from planning.cycles.piles import setup_frames

    model = ctx.models(params.robot)
    plan = params.pile_plan()   # the job's own reading of the plan (rows or CSV)
    where = {pid: k for k, pid in enumerate(plan.ids)}
    S = np.array([[s.x, s.y, s.heading] for s in result.setups], dtype=float).reshape(-1, 3)
    frames = setup_frames(S, params.base_height) if len(S) else np.zeros((0, 4, 4))
    strokes, colors = [], []
    capsules, spheres, polylines = [], [], []
    first: dict[int, Any] = {}
    heads: dict[int, list[np.ndarray]] = {}
    for j, p in enumerate(result.piles):
        k = where.get(p.id)
        if k is None:
            raise ValueError(f"result.piles.{j}.id: the plan has no pile {p.id!r}")
        if not 0 <= p.setup < len(S):
            raise ValueError(f"result.piles.{j}.setup: set-ups are numbered 0 to "
                             f"{len(S) - 1}, got {p.setup}")
        color = SETUP_COLORS[p.setup % len(SETUP_COLORS)]
        strokes.append([plan.heads[k], plan.heads[k] + PILE_STROKE_MM * plan.axes[k]])
        colors.append([color])
        heads.setdefault(p.setup, []).append(plan.heads[k])
        if p.setup not in first or p.order < first[p.setup][0]:
            first[p.setup] = (p.order, _joints([p.q], f"result.piles.{j}.q", model)[0])
    for u in result.unreached:
        k = where.get(u.id)
        if k is not None:
            strokes.append([plan.heads[k], plan.heads[k] + PILE_STROKE_MM * plan.axes[k]])
            colors.append([HOLE_UNREACHABLE_COLOR])
    radius = max(params.carrier_radius, 150.0)
    for s in range(len(S)):
        color = SETUP_COLORS[s % len(SETUP_COLORS)]
        base = frames[s, :3, 3]
        capsules.append(Capsule(f"setups/{s}/carrier", np.array([base[0], base[1], 0.0]),
                                base, radius, color))
        if s in heads:
            H = np.array(heads[s])
            spheres.append(Spheres(f"setups/{s}/piles", H, np.full(len(H), 120.0), color))
        if s in first:
            joints = frames[s] @ fk_frames(model, first[s][1])   # (dof + 1, 4, 4), site
            polylines.append(Polyline(f"setups/{s}/arm", joints[:, :3, 3], color, width=3.0))
    route = S[:, :2]
    if params.carrier_start is not None and len(S):
        route = np.vstack([[params.carrier_start], route])
    if len(route) > 1:
        polylines.append(Polyline("route", np.column_stack([route, np.zeros(len(route))]),
                                  (90, 90, 90)))
    timed = ()
    if strokes:
        P = np.array(strokes, dtype=float)
        timed = (TimedSegments("piles", P, np.zeros((len(P), 0)), np.array(colors),
                               width=2.0),)
    site = ()
    if params.scene is not None:
        objects = collision_scene(params.scene).objects
        site = (Site("scene", tuple(objects)),) if objects else ()
    lines = [f"**Pile plan** for {code(model.id)} (job {code(ctx.job)}): "
             f"{result.piles_reached} of {result.piles_total} piles from {len(S)} set-up(s) "
             f"({plain(result.cover.method)}"
             + (", proven fewest" if result.cover.optimal else "") + ")",
             f"- cycle: {result.cycle_time_s:,.0f} s (work {result.work_s:,.0f} s, "
             f"relocation {result.relocation_s:,.0f} s, carrier travel "
             f"{result.travel_mm / 1000:,.1f} m)"]
    for s, so in enumerate(result.setups):
        lines.append(f"- set-up {s}: ({so.x:,.0f}, {so.y:,.0f}) mm, heading "
                     f"{math.degrees(so.heading):.0f}°, {so.piles} piles, "
                     f"{so.start:,.0f}–{so.end:,.0f} s")
    if result.unreached:
        lines.append(f"- **{len(result.unreached)} pile(s) unreached** (red)")
    lines.append("- piles: a stroke down the axis from the head, coloured by set-up; at each "
                 "set-up the carrier (a post) and the arm at its first pile (a line through "
                 "its joints); grey: the carrier's route. The robot model is not moved to "
                 "the set-ups")
    return Plan(ctx.job, "piles", capsules=tuple(capsules), spheres=tuple(spheres),
                polylines=tuple(polylines), timed=timed, sites=site,
                summary="\n".join(lines))


def _parse(model: type[BaseModel], value: Any, where: str) -> Any:
    if isinstance(value, model):
        return value
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a JSON object")
    try:
        return model.model_validate(value)
    except ValidationError as exc:
        raise ValueError(error_text(exc, where)) from None


def plan_from_result(kind: str, params: Any, result: Any, *, job: str = "",
                     models: ModelLookup, rigs: Mapping[str, Any] | None = None,
                     problem: int | None = None) -> Plan:
    """The ``Plan`` of a succeeded job of ``kind`` with ``params`` and ``result`` (JSON
    objects, or the kind's models).

    ``models(id)`` resolves a robot id (``KeyError`` if unknown), ``rigs`` maps rig ids to
    ``kinematics.rigs.Rig``; ``problem`` picks the problem of a batch (``picks_problems``
    kinds; default: the drawer's choice). ValueError for a kind the viewer cannot draw, or
    params or a result that do not match the kind's models (the message names the key);
    ``FieldError`` at ``("problem",)`` for a problem the job does not have.
    """
    draw = DRAWERS.get(kind)
    if draw is None:
        raise ValueError(f"the viewer cannot show jobs of kind '{kind}'; it shows "
                         f"{', '.join(DRAWERS)}")
    if problem is not None and not picks_problems(kind):
        raise FieldError(("problem",), f"jobs of kind '{kind}' plan no batch of problems; "
                         "give no problem")
    spec = KINDS[kind]
    typed_params = _parse(spec.params, params, "params")
    typed_result = _parse(spec.result, result, "result")

    def lookup(robot_id: str) -> RobotModel:
        try:
            return models(robot_id)
        except KeyError:
            raise ValueError(f"params.robot: unknown robot {robot_id!r}") from None

    return draw(typed_params, typed_result, DrawContext(job, lookup, rigs or {}, problem))
