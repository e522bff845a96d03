"""Obstacle-avoiding paths for a robot's tool, checked for reach and whole-arm clearance
(paper 000, section 4.5: plan the tool path, solve IK along it, convert to cylinder lengths).

Pipeline of ``plan_arm_path``:

1. Both endpoints must be reachable: position IK (the path fixes where the tool point goes,
   not how it is turned) from a seeded table of in-limit configurations. An unreachable
   endpoint is a clear failure naming why (e.g. the paper's goal [1800, 1800, 800] mm lies
   2669 mm from pile_driver's base, beyond its ~1916 mm reach).
2. The tool path is planned among the obstacles with ``planners.plan_path``.
3. The path is sampled densely (``spacing`` mm) and each sample solved by damped least
   squares on the position, starting from the previous sample's joints and projected onto
   the joint limits, so the arm stays on one branch and within its limits. A sample the
   tool cannot reach is a failure naming where.
   The tool path keeps the largest link radius (the last links end at the tool point) and a
   small slack on top of the safety margin.
4. Whole-arm clearance at every sample: each link is a capsule between consecutive
   ``fk_frames`` origins with a radius per link (default 60 mm), and must keep the scene's
   safety margin from every obstacle.
5. A joint trajectory through joint waypoints taken every ``waypoint_spacing`` mm of tool
   path, at rest at both ends. ``timing="optimal"`` (default): the C4 spline through them
   (``JointPath.through``) timed as fast as the robot's limits allow (``topp``: its joint
   speed limits, its cylinders' extension and retraction speeds and its pump flow, and the
   ``acceleration`` and ``jerk`` limits, by default ``ARM_ACCELERATION``/``ARM_JERK``);
   ``timing="uniform"``: the quintic B-spline (``bspline.quintic_bspline``) timed by arc
   length over ``duration`` s. Either is re-checked (limits, whole-arm clearance) on a fine
   grid.
6. For robots with cylinders (pile_driver) the cylinder lengths along the path and whether
   they stay within stroke.

Lengths in mm, angles in rad, times in s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.cylinders import CylinderError, CylinderSet
from kinematics.errors import FieldError
from kinematics.fk import fk, fk_frames
from kinematics.ik.position import REACH_TOL, position_ik, reach
from kinematics.ik.position import position_dls as _dls
from kinematics.model import RobotModel
from kinematics.numbers import finite_or_none

from ..budget import ProgressFn
from ..geometry.segments import segment_point_distance
from ..status import PlanStatus
from ..trajectories.bspline import quintic_bspline
from ..trajectories.hydraulic import hydraulic_limits
from ..trajectories.joint_path import JointPath
from ..trajectories.topp import time_optimal
from ..trajectories.trajectory import ARM_ACCELERATION, ARM_JERK, Limits, Trajectory
from .planners import PathResult, plan_path
from .scene import Capsule, Scene

__all__ = ["ArmPathResult", "plan_arm_path", "link_capsules", "arm_clearance"]

#: Default link radius (mm) of the capsules around each link.
DEFAULT_LINK_RADIUS = 60.0
#: Null-space gain towards mid-range while following the path (per IK iteration).
CENTRING = 0.02
#: Arm-path timings: as fast as the limits allow, or arc length over a given duration.
ARM_TIMINGS = ("optimal", "uniform")


@dataclass(frozen=True)
class ArmPathResult:
    """An arm path. ``tool`` is the planned tool path; ``points (S, 3)`` its dense samples at
    arc lengths ``s (S,)`` mm; ``q (S, dof)`` the joints there; ``trajectory`` the joint
    B-spline (None on failure before it); ``cylinders`` lengths (mm) by name ``(S,)`` for
    robots that have cylinders. ``arm_min_clearance``: least clearance (mm) of any link
    capsule to any obstacle over the samples. ``status``: ``ok``; the tool path's own
    failure; ``unreachable`` (an endpoint or a sample of the path out of reach);
    ``collision`` (a link hits an obstacle, at a sample or along the joint trajectory);
    ``out_of_limits`` (the joint trajectory leaves the joint limits or a cylinder its
    stroke). ``planner``: what produced the motion, ``tool_space`` (this module: the tool
    path, followed by IK) or ``joint_space`` (``planning.motion.arm_motion``)."""

    tool: PathResult
    points: np.ndarray
    s: np.ndarray
    q: np.ndarray
    trajectory: Trajectory | None
    cylinders: dict[str, np.ndarray] | None
    cylinders_within_stroke: bool | None
    arm_min_clearance: float
    status: PlanStatus
    message: str
    extra: dict = field(default_factory=dict)
    planner: str = "tool_space"

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK

    def to_dict(self, dt: float | None = None) -> dict[str, Any]:
        """JSON-ready dict: the tool path's fields plus ``joint_path``, ``trajectory``
        (sampled every ``dt`` s, default duration/200) and ``cylinders``."""
        out = self.tool.to_dict()
        out.update(success=self.success, status=self.status.value, message=self.message,
                   planner=self.planner,
                   arm_min_clearance=finite_or_none(self.arm_min_clearance),
                   joint_path=self.q.tolist(), tool_samples=self.points.tolist())
        if self.trajectory is not None:
            step = dt or self.trajectory.duration / 200
            smp = self.trajectory.sample(step)
            out["trajectory"] = {"t": smp.t.tolist(), "q": smp.q.tolist(),
                                 "qd": smp.qd.tolist(), "qdd": smp.qdd.tolist(),
                                 "waypoints": self.extra.get("waypoints", [])}
        else:
            out["trajectory"] = None
        if self.cylinders is not None:
            out["cylinders"] = {"lengths": {k: v.tolist() for k, v in self.cylinders.items()},
                                "within_stroke": self.cylinders_within_stroke}
        else:
            out["cylinders"] = None
        return out


# ---- whole-arm clearance ----------------------------------------------------------------
def link_capsules(model: RobotModel, q) -> tuple[np.ndarray, np.ndarray]:
    """Link segments of configurations ``q (N, dof)``: ``(A, B)`` each ``(N, dof, 3)``,
    between consecutive ``fk_frames`` origins (base, after each joint, tool)."""
    F = fk_frames(model, np.atleast_2d(q))[..., :3, 3]  # (N, dof+1, 3)
    return F[:, :-1], F[:, 1:]


def _radii(model: RobotModel, link_radius) -> np.ndarray:
    r = np.broadcast_to(np.asarray(link_radius, dtype=float), (model.dof,)).copy() \
        if np.ndim(link_radius) == 0 else np.asarray(link_radius, dtype=float)
    if r.shape != (model.dof,):
        raise FieldError("link_radius", f"link_radius must be one number or {model.dof} numbers")
    if not np.all(np.isfinite(r)) or np.any(r < 0):
        raise FieldError("link_radius", "link_radius must be finite and non-negative")
    return r


def arm_clearance(model: RobotModel, scene: Scene, q, link_radius=DEFAULT_LINK_RADIUS
                  ) -> np.ndarray:
    """Clearance (mm) of each link capsule to each obstacle: ``q (N, dof) ->
    (N, dof, n_obstacles)`` (negative = overlap)."""
    r = _radii(model, link_radius)
    A, B = link_capsules(model, q)
    N = len(A)
    c = scene.segment_clearance(A.reshape(-1, 3), B.reshape(-1, 3))
    return c.reshape(N, model.dof, -1) - r[None, :, None]


# ---- the pipeline -----------------------------------------------------------------------
def _resample(path: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(S, 3)`` along a polyline at most ``spacing`` apart (every vertex kept) and
    their arc lengths ``(S,)``."""
    pts, s = [path[:1]], [np.zeros(1)]
    cum = 0.0
    for a, b in zip(path[:-1], path[1:]):
        L = float(np.linalg.norm(b - a))
        m = max(1, math.ceil(L / spacing))
        f = np.arange(1, m + 1) / m
        pts.append(a + f[:, None] * (b - a))
        s.append(cum + f * L)
        cum += L
    return np.vstack(pts), np.concatenate(s)


def _fail(tool: PathResult, status: PlanStatus, message: str, **kw) -> ArmPathResult:
    empty = np.empty((0, 3))
    base = dict(points=empty, s=np.empty(0), q=np.empty((0, 0)), trajectory=None,
                cylinders=None, cylinders_within_stroke=None, arm_min_clearance=math.nan)
    base.update(kw)
    return ArmPathResult(tool=tool, status=status, message=message, **base)


def _unreachable(model: RobotModel, name: str, point: np.ndarray, err: float) -> str:
    d = float(np.linalg.norm(point - model.base[:3, 3]))
    R = reach(model)
    where = f"{name} {np.round(point, 3).tolist()} mm is unreachable for {model.id}: "
    if d > R:
        return where + (f"it lies {d:.0f} mm from the base, beyond the arm's reach of about "
                        f"{R:.0f} mm")
    return where + (f"no configuration within the joint limits puts the tool there (the "
                    f"closest found is {err:.1f} mm away)")


def _link_name(model: RobotModel, k: int) -> str:
    return f"link {k} (after joint '{model.joints[k].name}')" if k > 0 else "link 0 (base)"


class _Failed(Exception):
    """Raised by a step of ``plan_arm_path`` that ends the plan with a failed ``result``."""

    def __init__(self, result: ArmPathResult) -> None:
        super().__init__(result.message)
        self.result = result


@dataclass(frozen=True)
class _Samples:
    """The tool path sampled for IK: ``points (S, 3)`` mm at arc lengths ``s (S,)`` mm, and
    the joints ``q (S, dof)`` that put the tool there."""

    points: np.ndarray
    s: np.ndarray
    q: np.ndarray


@dataclass(frozen=True)
class _TrajectoryCheck:
    """The joint trajectory checked on a fine grid: within the joint limits, the least arm
    clearance (mm) and the largest tool departure from the tool path (mm); cylinder lengths
    at the samples (mm, by name) and whether they stay within stroke on both (None for a
    robot without cylinders)."""

    within_limits: bool
    min_clearance: float
    tool_deviation: float
    cylinders: dict[str, np.ndarray] | None
    cylinders_within_stroke: bool | None


def plan_arm_path(
    model: RobotModel,
    scene: Scene,
    start,
    goal,
    algorithm: str = "auto",
    seed: int = 0,
    params: dict[str, Any] | None = None,
    progress: ProgressFn | None = None,
    *,
    link_radius=DEFAULT_LINK_RADIUS,
    spacing: float = 10.0,
    waypoint_spacing: float = 25.0,
    clearance_slack: float = 5.0,
    duration: float = 10.0,
    q_start=None,
    keep_out_radius: float | None = None,
    timing: str = "optimal",
    acceleration=None,
    jerk=None,
) -> ArmPathResult:
    """Plan the tool of ``model`` from ``start`` to ``goal`` (mm, world frame) in ``scene``.

    ``link_radius``: mm, one number or one per link (``dof``); ``spacing``: mm between IK
    samples; ``waypoint_spacing``: mm of tool path between trajectory waypoints;
    ``duration``: s of the joint trajectory; ``clearance_slack``: mm the tool path keeps
    on top of margin and link radius; ``q_start``: joints to start from (default:
    position IK); ``keep_out_radius``: mm, keeps the tool path that far from the base's z
    axis (``base_keep_out``; the arm itself is checked against the scene only);
    ``timing``: 'optimal' (the fastest within the robot's limits and ``acceleration``,
    ``jerk``: one number or one per joint, defaults ``ARM_ACCELERATION``, ``ARM_JERK``;
    ``duration`` is then not used) or 'uniform' (``duration`` s). Invalid input raises
    ``FieldError`` naming the field; unreachable endpoints, a tool path the arm
    cannot follow and arm collisions give a failed ``status``.

    The steps, as in the module docstring: the endpoints' joints (``_endpoint_joints``),
    the tool path (``_tool_scene``, ``plan_path``), IK along it (``_follow``), whole-arm
    clearance (``_check_arm``), the joint trajectory (``_joint_trajectory``) and its check
    with the cylinders (``_check_trajectory``), and the result (``_result``).
    """
    radii = _checked_options(model, link_radius, spacing=spacing,
                             waypoint_spacing=waypoint_spacing,
                             clearance_slack=clearance_slack, duration=duration)
    if timing not in ARM_TIMINGS:
        raise FieldError("timing", f"timing must be one of {', '.join(ARM_TIMINGS)}")
    rates = _arm_limits(model, acceleration, jerk) if timing == "optimal" else None
    start = scene.check_endpoint(start, "start")
    goal = scene.check_endpoint(goal, "goal")
    report = progress or (lambda f: None)
    try:
        q0, q_goal = _endpoint_joints(model, start, goal, q_start, algorithm)
        report(0.05)
        tool_scene = _tool_scene(model, scene, radii, clearance_slack, keep_out_radius)
        tool_scene.check_endpoint(start, "start")
        tool_scene.check_endpoint(goal, "goal")
        tool = plan_path(tool_scene, start, goal, algorithm, seed, params,
                         progress=lambda f: report(0.05 + 0.6 * f))
        if not tool.success:
            raise _Failed(_fail(tool, tool.status, tool.message))
        samples = _follow(model, tool, spacing, q0)
        report(0.8)
        arm_min = _check_arm(model, scene, radii, tool, samples)
    except _Failed as failed:
        return failed.result
    traj, waypoints = _joint_trajectory(samples, waypoint_spacing, duration)
    if rates is not None:
        traj = _optimal_timing(model, samples.q[waypoints], rates, traj)
    check = _check_trajectory(model, scene, radii, tool, samples, traj)
    report(1.0)
    return _result(tool, samples, traj, waypoints, check, arm_min, q_goal,
                   scene.safety_margin)


def _checked_options(model: RobotModel, link_radius, *, spacing: float,
                     waypoint_spacing: float, clearance_slack: float,
                     duration: float) -> np.ndarray:
    """``FieldError`` naming an option out of range; the link radii ``(dof,)`` mm."""
    if not (isinstance(clearance_slack, int | float) and clearance_slack >= 0):
        raise FieldError("clearance_slack", "clearance_slack must be a non-negative number")
    for name, value in (("spacing", spacing), ("waypoint_spacing", waypoint_spacing),
                        ("duration", duration)):
        if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
            raise FieldError(name, f"{name} must be a positive number")
    return _radii(model, link_radius)


def _endpoint_joints(model: RobotModel, start: np.ndarray, goal: np.ndarray, q_start,
                     algorithm: str) -> tuple[np.ndarray, np.ndarray]:
    """Joints at the start (``q_start``, checked, or position IK) and at the goal (position
    IK). ``_Failed`` (``unreachable``, saying why) for an endpoint out of reach."""
    nothing = PathResult(np.empty((0, 3)), math.inf, math.nan, 0.0, np.empty(0), algorithm,
                         0, PlanStatus.UNREACHABLE, "not planned")
    if q_start is not None:
        q_start = np.asarray(q_start, dtype=float)
        if q_start.shape != (model.dof,) or not np.all(np.isfinite(q_start)):
            raise FieldError("q_start", f"q_start must be {model.dof} finite numbers")
        if not model.within_limits(q_start):
            raise FieldError("q_start", "q_start is outside the joint limits: "
                             + ", ".join(model.limit_violations(q_start)))
        if np.linalg.norm(fk(model, q_start)[:3, 3] - start) > REACH_TOL:
            raise FieldError("q_start", "q_start does not put the tool at start")
        q0 = q_start
    else:
        q0, err = position_ik(model, start)
        if q0 is None:
            raise _Failed(_fail(nothing, PlanStatus.UNREACHABLE,
                                _unreachable(model, "start", start, err)))
    q_goal, err = position_ik(model, goal)
    if q_goal is None:
        raise _Failed(_fail(nothing, PlanStatus.UNREACHABLE,
                            _unreachable(model, "goal", goal, err)))
    return q0, q_goal


def _tool_scene(model: RobotModel, scene: Scene, radii: np.ndarray, clearance_slack: float,
                keep_out_radius: float | None) -> Scene:
    """The scene the tool path is planned in. The tool point carries the end of the last
    links: its path keeps their radius (the largest link radius) on top of the safety
    margin, plus ``clearance_slack`` for the joint spline's small departures from the path
    between waypoints; with ``keep_out_radius``, also ``base_keep_out``."""
    tool_scene = Scene(scene.lower, scene.upper, scene.obstacles,
                       scene.safety_margin + float(radii.max()) + clearance_slack)
    if keep_out_radius is not None:
        if not (math.isfinite(keep_out_radius) and keep_out_radius > 0):
            raise FieldError("keep_out_radius", "keep_out_radius must be a positive number")
        tool_scene = tool_scene.with_obstacles([base_keep_out(model, keep_out_radius)])
    return tool_scene


def _follow(model: RobotModel, tool: PathResult, spacing: float, q0: np.ndarray) -> _Samples:
    """The tool path every ``spacing`` mm, each sample solved by damped least squares from
    the previous one's joints (within the limits, centred). ``_Failed`` (``unreachable``,
    naming where) at the first sample out of reach."""
    points, s = _resample(tool.path, spacing)
    Q = np.empty((len(points), model.dof))
    q = q0
    for i, p in enumerate(points):
        qn, e = _dls(model, q[None], p, 50, REACH_TOL / 10, centring=CENTRING)
        if e[0] > REACH_TOL:
            raise _Failed(_fail(
                tool, PlanStatus.UNREACHABLE,
                f"the tool path leaves the arm's reach at {s[i]:.0f} mm along it, "
                f"{np.round(p, 1).tolist()} mm (closest reachable {e[0]:.1f} mm away)",
                points=points[:i], s=s[:i], q=Q[:i]))
        q = qn[0]
        Q[i] = q
    return _Samples(points, s, Q)


def _check_arm(model: RobotModel, scene: Scene, radii: np.ndarray, tool: PathResult,
               samples: _Samples) -> float:
    """The least clearance (mm) of any link to any obstacle over the samples; ``_Failed``
    (``collision``, naming the link, the obstacle and where) below the safety margin."""
    C = arm_clearance(model, scene, samples.q, radii) if scene.obstacles else \
        np.full((len(samples.q), model.dof, 1), np.inf)
    arm_min = float(C.min())
    if arm_min < scene.safety_margin:
        i, k, j = np.unravel_index(int(np.argmin(C)), C.shape)
        raise _Failed(_fail(
            tool, PlanStatus.COLLISION,
            f"the arm hits an obstacle: {_link_name(model, int(k))} comes "
            f"{C[i, k, j]:.1f} mm from obstacles[{j}] (needs {scene.safety_margin} mm) at "
            f"{samples.s[i]:.0f} mm along the tool path",
            points=samples.points, s=samples.s, q=samples.q, arm_min_clearance=arm_min))
    return arm_min


def _joint_trajectory(samples: _Samples, waypoint_spacing: float, duration: float
                      ) -> tuple[Trajectory, np.ndarray]:
    """The quintic B-spline through the joints every ``waypoint_spacing`` mm of tool path
    (first and last sample included), timed by arc length over ``duration`` s; and the
    indices of the samples it passes through."""
    s = samples.s
    n_wp = max(1, math.ceil(s[-1] / waypoint_spacing)) if s[-1] > 0 else 1
    idx = np.unique(np.searchsorted(s, np.linspace(0, s[-1], n_wp + 1)))
    idx[-1] = len(s) - 1
    idx = np.unique(idx)
    if len(idx) < 2:
        idx = np.array([0, len(s) - 1])
    durations = np.diff(s[idx]) / max(s[-1], 1e-12) * duration
    if np.any(durations <= 0):
        durations = np.full(len(idx) - 1, duration / (len(idx) - 1))
    return quintic_bspline(samples.q[idx], durations), idx


def _arm_limits(model: RobotModel, acceleration, jerk) -> Limits:
    """The rate limits of optimal arm-path timing: the robot's joint speed limits and the
    given (or default) accelerations and jerks; ``FieldError`` naming the one at fault."""
    out = {}
    for name, value, default in (("acceleration", acceleration, ARM_ACCELERATION),
                                 ("jerk", jerk, ARM_JERK)):
        if value is None:
            arr = np.where(model.revolute, default[0], default[1])
        else:
            arr = np.asarray(value, dtype=float)
            arr = np.broadcast_to(arr, (model.dof,)).copy() if arr.ndim == 0 else arr
        if arr.shape != (model.dof,) or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise FieldError(name, f"{name} must be one positive number or {model.dof}")
        out[name] = arr
    return Limits(velocity=np.asarray(model.velocity_limits), **out)


def _optimal_timing(model: RobotModel, waypoints: np.ndarray, limits: Limits,
                    fallback: Trajectory) -> Trajectory:
    """The spline through ``waypoints`` timed as fast as ``limits`` and the robot's
    hydraulics allow (jerk-limited); ``fallback`` when the waypoints do not move."""
    try:
        path = JointPath.through(waypoints)
    except FieldError:  # start and goal coincide: nothing to time
        return fallback
    res = time_optimal(path, limits, hydraulic_limits(model))
    return res.trajectory if res.success else fallback


def _check_trajectory(model: RobotModel, scene: Scene, radii: np.ndarray, tool: PathResult,
                      samples: _Samples, traj: Trajectory) -> _TrajectoryCheck:
    """``traj`` on a grid of at least 200 and twice the samples' count: joint limits, arm
    clearance, tool departure from the tool path; cylinder lengths and strokes."""
    t_check = np.linspace(0.0, traj.duration, max(200, 2 * len(samples.s)))
    Qt = traj.evaluate(t_check)
    limits_ok = bool(np.all(model.within_limits(Qt, tol=1e-6)))
    Ct = arm_clearance(model, scene, Qt, radii).min() if scene.obstacles else math.inf
    tool_dev = _deviation(fk(model, Qt)[:, :3, 3], tool.path)
    cyl, cyl_ok = None, None
    try:
        cs = CylinderSet.from_model(model)
    except CylinderError:
        cs = None
    if cs is not None:
        cyl = cs.lengths(samples.q)
        ok_t = cs.within_stroke(cs.lengths(Qt), tol=1e-6)
        cyl_ok = bool(all(np.all(v) for v in cs.within_stroke(cyl).values())
                      and all(np.all(v) for v in ok_t.values()))
    return _TrajectoryCheck(limits_ok, float(Ct), tool_dev, cyl, cyl_ok)


def _result(tool: PathResult, samples: _Samples, traj: Trajectory, waypoints: np.ndarray,
            check: _TrajectoryCheck, arm_min: float, q_goal: np.ndarray,
            safety_margin: float) -> ArmPathResult:
    """The planned arm path; its status that of the first problem the trajectory check
    found (limits, clearance, cylinder strokes), every problem in its message."""
    extra = {"waypoints": samples.q[waypoints].tolist(),
             "trajectory_min_clearance": check.min_clearance,
             "trajectory_within_limits": check.within_limits,
             "trajectory_tool_deviation": check.tool_deviation,
             "q_goal_ik": q_goal.tolist()}
    problems: list[tuple[PlanStatus, str]] = []
    if not check.within_limits:
        problems.append((PlanStatus.OUT_OF_LIMITS,
                         "the joint trajectory leaves the joint limits between waypoints"))
    if check.min_clearance < safety_margin:
        problems.append((PlanStatus.COLLISION,
                         f"the joint trajectory brings the arm {check.min_clearance:.1f} mm "
                         "from an obstacle between waypoints (try a smaller "
                         "waypoint_spacing)"))
    if check.cylinders_within_stroke is False:
        problems.append((PlanStatus.OUT_OF_LIMITS, "a cylinder leaves its stroke"))
    return ArmPathResult(
        tool=tool, points=samples.points, s=samples.s, q=samples.q, trajectory=traj,
        cylinders=check.cylinders, cylinders_within_stroke=check.cylinders_within_stroke,
        arm_min_clearance=arm_min,
        status=problems[0][0] if problems else PlanStatus.OK,
        message="; ".join(why for _, why in problems) if problems else
        "clear tool path, reachable at every sample, whole arm clear", extra=extra)


def _deviation(points: np.ndarray, path: np.ndarray) -> float:
    """Largest distance (mm) from ``points (M, 3)`` to the polyline ``path (n, 3)``."""
    d, _ = segment_point_distance(path[None, :-1], path[None, 1:], points[:, None, :])
    return float(d.min(axis=1).max())


def base_keep_out(model: RobotModel, radius: float, height: float | None = None) -> Capsule:
    """A vertical capsule of ``radius`` mm on the base z axis (``height`` mm up and down,
    default twice the reach): an obstacle for the *tool* that keeps its path out of the
    hollow near the base axis that an arm like pile_driver cannot reach."""
    h = 2 * reach(model) if height is None else height
    o = model.base[:3, 3]
    z = model.base[:3, 2]
    return Capsule(o - h * z, o + h * z, radius)
