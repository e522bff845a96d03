"""An arm's move from a start to a goal: the tool path when the arm can follow it, otherwise a
joint-space motion (``planning.motion.plan_motion``) in the same obstacles.

``plan_arm_path`` plans the tool point's path in Cartesian space and follows it by IK. Where
the straight-line-ish tool route leaves the arm's reach (pile_driver's hollow near its swing
axis, the palletizer's wrist flips), where IK cannot follow it within the joint limits, or
where the links hit an obstacle on the way, no tool path exists that this pipeline can follow,
yet the arm can still move there. ``plan_arm_motion`` then plans in joint space:

* the start configuration: the given ``q_start``, else the position IK solution the arm
  planner picks (``kinematics.ik.position.position_ik``), else a solution found from more
  starts up to the joint limits themselves;
* the goal: the given ``q_goal`` (always planned in joint space), else every distinct
  position IK solution of the goal point that is free (the point fixes where the tool goes,
  not how the arm is folded), nearest the start first, tried in turn within the time limit;
* the obstacles: the path scene's spheres, boxes and capsules as a
  ``planning.collision.CollisionScene`` (or, for a stored scene, its own objects: meshes and
  point clouds as they are, not their bounding boxes), kept ``safety_margin`` away;
* the arm: the capsule collision model of ``RobotCollisionModel.from_model`` with the arm
  options' ``link_radius`` (the capsules ``plan_arm_path`` checks), itself included.

The result keeps ``ArmPathResult``'s shape: the tool path is the tool point's route by FK
along the joint path, sampled at most ``spacing`` mm apart (``points``, ``q``), the
trajectory is the motion planner's time-optimal one (its geometric path checked free) or,
with ``timing="uniform"``, the same path stretched to ``duration``; ``planner`` says which
planner produced the motion (``"tool_space"`` or ``"joint_space"``). The scene's bounds
delimit the tool path's search only: the joint-space planner checks the arm against the
obstacles, not the tool point against the bounds.

Lengths in mm, angles in rad, times in s.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from kinematics.cylinders import CylinderError, CylinderSet
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.ik.position import REACH_TOL, position_dls, position_ik
from kinematics.model import RobotModel
from planning.collision import CollisionScene, RobotCollisionModel

from ..budget import ProgressFn
from ..paths.arm import (
    ARM_TIMINGS,
    DEFAULT_LINK_RADIUS,
    ArmPathResult,
    _arm_limits,
    _checked_options,
    _fail,
    arm_clearance,
    plan_arm_path,
)
from ..paths.planners import PathResult
from ..paths.scene import Scene
from ..status import PlanStatus
from .checker import DEFAULT_RESOLUTION, PRISMATIC_STEP, MotionChecker
from .planner import MotionStatus, plan_motion

__all__ = ["JOINT_SPACE_MODES", "DEFAULT_JOINT_TIME_LIMIT", "plan_arm_motion",
           "collision_scene_of", "point_configurations"]

#: When the joint-space planner plans the move: ``fallback`` (when the tool path cannot be
#: followed), ``always``, ``never`` (the tool path or nothing).
JOINT_SPACE_MODES = ("fallback", "always", "never")
#: Search time of the joint-space planner (s) over all goal configurations tried.
DEFAULT_JOINT_TIME_LIMIT = 5.0
#: Random starts of the position IK that looks for goal (and hard start) configurations.
ENDPOINT_STARTS = 64
#: Iterations of that IK.
ENDPOINT_ITERATIONS = 200
#: Goal configurations closer than this (rad; mm / 100 for prismatic joints, largest joint
#: difference) count as one.
DISTINCT_BRANCH = 0.05
#: Most goal configurations tried in turn: the first gets half of the time limit, the others
#: share the rest.
GOAL_TRIES = 3
#: Largest joint step (rad; x 100 mm for prismatic joints) between the returned samples.
SAMPLE_JOINT_STEP = 0.02
#: Joint-space statuses as the arm path's.
_STATUS = {
    MotionStatus.START_IN_COLLISION: PlanStatus.COLLISION,
    MotionStatus.GOAL_IN_COLLISION: PlanStatus.COLLISION,
    MotionStatus.GOAL_UNREACHABLE: PlanStatus.UNREACHABLE,
    MotionStatus.OUT_OF_LIMITS: PlanStatus.OUT_OF_LIMITS,
    MotionStatus.NO_PATH: PlanStatus.NO_PATH,
    MotionStatus.TIMEOUT: PlanStatus.BUDGET_SPENT,
}


# ---- the scene --------------------------------------------------------------------------
def collision_scene_of(scene: Scene) -> CollisionScene:
    """The path scene's obstacles as a ``CollisionScene`` (exactly the same shapes): a sphere
    as a sphere, an axis-aligned box as a box, a capsule as a capsule; object ``i`` has the
    id ``obstacles[i]``, as the path planners name it. The bounds are not obstacles."""
    objects = []
    for i, o in enumerate(scene.obstacles):
        oid = f"obstacles[{i}]"
        if o.kind == "sphere":
            objects.append({"type": "sphere", "id": oid, "radius": float(o.radius),
                            "pose": _translation(o.center)})
        elif o.kind == "box":
            objects.append({"type": "box", "id": oid, "size": (o.upper - o.lower).tolist(),
                            "pose": _translation((o.lower + o.upper) / 2)})
        else:
            objects.append({"type": "capsule", "id": oid, "a": o.a.tolist(),
                            "b": o.b.tolist(), "radius": float(o.radius)})
    return CollisionScene.from_dicts(objects, prefix=("scene", "obstacles"))


def _translation(p: np.ndarray) -> list[list[float]]:
    T = np.eye(4)
    T[:3, 3] = p
    return T.tolist()


# ---- endpoint configurations --------------------------------------------------------------
def _finite_limits(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Joint limits with unbounded revolute joints taken as one turn (for sampling)."""
    lo = np.where(np.isfinite(model.lower), model.lower, -math.pi)
    hi = np.where(np.isfinite(model.upper), model.upper, math.pi)
    return lo, hi


def point_configurations(model: RobotModel, point, seed: int = 0, q_ref=None,
                         starts: int = ENDPOINT_STARTS) -> np.ndarray:
    """Distinct in-limit configurations ``(K, dof)`` that put the tool point at ``point (3,)``
    mm (within ``REACH_TOL``), nearest ``q_ref`` first (weighted joint distance; default the
    mid-range). Position IK by damped least squares up to the joint limits themselves from
    ``q_ref``, the arm planner's own pick and ``starts`` seeded random configurations; K may
    be 0."""
    point = np.asarray(point, dtype=float)
    lo, hi = _finite_limits(model)
    rows = []
    if q_ref is not None:
        rows.append(np.asarray(q_ref, dtype=float)[None])
    q_ik, _ = position_ik(model, point)
    if q_ik is not None:
        rows.append(q_ik[None])
    rng = np.random.default_rng(seed)
    rows.append(rng.uniform(lo, hi, size=(starts, model.dof)))
    Q, err = position_dls(model, np.vstack(rows), point, ENDPOINT_ITERATIONS, REACH_TOL / 10,
                          inset=0.0)
    ok = (err < REACH_TOL) & model.within_limits(Q)
    Q = Q[ok]
    if len(Q) == 0:
        return Q.reshape(0, model.dof)
    w = np.where(model.revolute, 1.0, 1.0 / PRISMATIC_STEP)
    ref = model.mid_configuration() if q_ref is None else np.asarray(q_ref, dtype=float)
    ref = np.where(np.isfinite(ref), ref, 0.0)
    Q = Q[np.argsort(np.linalg.norm((Q - ref) * w, axis=1), kind="stable")]
    keep = [0]
    for i in range(1, len(Q)):
        if np.min(np.max(np.abs(Q[keep] - Q[i]) * w, axis=1)) > DISTINCT_BRANCH:
            keep.append(i)
    return Q[keep]


def _configuration(model: RobotModel, value, name: str) -> np.ndarray | None:
    """A given configuration, checked: ``FieldError`` at ``(name,)``."""
    if value is None:
        return None
    q = np.asarray(value, dtype=float)
    if q.shape != (model.dof,) or not np.all(np.isfinite(q)):
        raise FieldError(name, f"{name} must be {model.dof} finite numbers")
    if not model.within_limits(q):
        raise FieldError(name, f"{name} is outside the joint limits: "
                         + ", ".join(model.limit_violations(q)))
    return q


def _endpoint(model: RobotModel, scene: Scene, point, q: np.ndarray | None, name: str,
              q_name: str) -> np.ndarray:
    """The endpoint's tool point: the given point (checked against the scene, and against
    ``q`` when both are given) or the tool point of ``q``."""
    if point is None:
        if q is None:
            raise FieldError(name, f"give {name} (a tool point, mm) or {q_name} (joint values)")
        return fk(model, q)[:3, 3]
    p = scene.check_endpoint(point, name)
    if q is not None and np.linalg.norm(fk(model, q)[:3, 3] - p) > REACH_TOL:
        raise FieldError(q_name, f"{q_name} does not put the tool at {name}")
    return p


# ---- the plan ----------------------------------------------------------------------------
def plan_arm_motion(
    model: RobotModel,
    scene: Scene,
    start=None,
    goal=None,
    algorithm: str = "auto",
    seed: int = 0,
    params: dict[str, Any] | None = None,
    progress: ProgressFn | None = None,
    *,
    q_start=None,
    q_goal=None,
    joint_space: str = "fallback",
    joint_time_limit: float = DEFAULT_JOINT_TIME_LIMIT,
    joint_planner: str = "auto",
    resolution: float = DEFAULT_RESOLUTION,
    objects: CollisionScene | None = None,
    link_radius=DEFAULT_LINK_RADIUS,
    spacing: float = 10.0,
    timing: str = "optimal",
    duration: float = 10.0,
    acceleration=None,
    jerk=None,
    **tool_options: Any,
) -> ArmPathResult:
    """Move ``model``'s tool from ``start`` to ``goal`` (mm, world frame; either may be left
    out when ``q_start`` / ``q_goal`` gives the configuration) in ``scene`` (module
    docstring).

    ``joint_space``: ``fallback`` (default: the tool path of ``plan_arm_path`` first, the
    joint-space motion when that fails), ``always`` or ``never``; a ``q_goal`` is always
    reached in joint space. ``joint_time_limit`` (s), ``joint_planner`` and ``resolution``
    (rad between checked states) go to ``plan_motion``; ``objects``: the scene's real
    geometry for the joint-space planner (default: the obstacles themselves). The other
    options (``algorithm``, ``seed``, ``params``, ``link_radius``, ``spacing``, ``timing``,
    ``duration``, ``acceleration``, ``jerk`` and ``tool_options``) are ``plan_arm_path``'s.

    A failed fallback returns the tool path's failure, its message followed by the
    joint-space planner's reason. Invalid input raises ``FieldError`` naming the field."""
    t0 = time.perf_counter()
    if joint_space not in JOINT_SPACE_MODES:
        raise FieldError("joint_space", f"joint_space must be one of "
                         f"{', '.join(JOINT_SPACE_MODES)}")
    if timing not in ARM_TIMINGS:
        raise FieldError("timing", f"timing must be one of {', '.join(ARM_TIMINGS)}")
    qs = _configuration(model, q_start, "q_start")
    qg = _configuration(model, q_goal, "q_goal")
    if qg is not None and joint_space == "never":
        raise FieldError("joint_space", "a goal configuration (q_goal) is reached in joint "
                         "space: joint_space cannot be 'never'")
    radii = _checked_options(model, link_radius, spacing=spacing,
                             waypoint_spacing=tool_options.get("waypoint_spacing", 25.0),
                             clearance_slack=tool_options.get("clearance_slack", 5.0),
                             duration=duration)
    rates = _arm_limits(model, acceleration, jerk)
    p_start = _endpoint(model, scene, start, qs, "start", "q_start")
    p_goal = _endpoint(model, scene, goal, qg, "goal", "q_goal")
    report = progress or (lambda f: None)

    tool = None
    if joint_space != "always" and qg is None:
        share = 1.0 if joint_space == "never" else 0.5
        tool = plan_arm_path(model, scene, p_start, p_goal, algorithm, seed, params,
                             lambda f: report(share * f), link_radius=link_radius,
                             spacing=spacing, q_start=qs, timing=timing, duration=duration,
                             acceleration=acceleration, jerk=jerk, **tool_options)
        if tool.success or joint_space == "never":
            return tool

    done = 0.0 if tool is None else 0.5
    motion, why = _joint_motion(model, scene, objects, radii, p_start, p_goal, qs, qg, seed,
                                joint_planner, joint_time_limit, resolution, rates,
                                lambda f: report(done + (1.0 - done) * f))
    if motion is None or not motion.success:
        if tool is not None:
            return _with_note(tool, f"; joint space: {why}")
        empty = PathResult(np.empty((0, 3)), math.inf, math.nan, time.perf_counter() - t0,
                           np.empty(0), joint_planner, 0, PlanStatus.NO_PATH, why)
        status = _STATUS.get(motion.status, PlanStatus.NO_PATH) if motion is not None \
            else PlanStatus.UNREACHABLE
        return _fail(empty, status, f"joint space: {why}", planner="joint_space")
    reason = "" if tool is None else tool.message
    out = _joint_result(model, scene, objects, radii, motion, spacing, timing, duration,
                        reason, time.perf_counter() - t0)
    report(1.0)
    return out


def _with_note(res: ArmPathResult, note: str) -> ArmPathResult:
    return replace(res, message=res.message + note)


def _checker(model: RobotModel, scene: Scene, objects: CollisionScene | None,
             radii: np.ndarray, self_collision: bool = True) -> MotionChecker:
    cm = RobotCollisionModel.from_model(model, radii)
    cs = objects if objects is not None else collision_scene_of(scene)
    return MotionChecker(cm, cs, margin=scene.safety_margin, self_collision=self_collision)


def _joint_motion(model, scene, objects, radii, p_start, p_goal, qs, qg, seed, planner,
                  time_limit, resolution, rates, progress):
    """The joint-space motion (``MotionResult``, None when an endpoint has no configuration)
    and, when it failed, why in words."""
    checker = _checker(model, scene, objects, radii)
    if qs is None:
        # The arm planner's pick when it is free, else the first free one found.
        picked, _ = position_ik(model, p_start)
        if picked is None or not checker.free(picked):
            found = point_configurations(model, p_start, seed)
            if len(found) == 0:
                return None, "no configuration within the joint limits puts the tool at " \
                    "the start"
            free = np.atleast_1d(checker.free(found))
            picked = found[int(np.argmax(free))]  # all colliding: plan_motion names why
        qs = picked
    if qg is not None:
        goals = qg[None]
    else:
        goals = point_configurations(model, p_goal, seed, q_ref=qs)
        if len(goals) == 0:
            return None, "no configuration within the joint limits puts the tool at the goal"
        free = np.atleast_1d(checker.free(goals))
        if free.any():
            goals = goals[free]
        else:
            goals = goals[:1]  # plan_motion names the colliding pair
    deadline = time.perf_counter() + time_limit
    tries = goals[:GOAL_TRIES]
    motion = None
    for k, q_goal in enumerate(tries):
        left = deadline - time.perf_counter()
        if left <= 0:
            break
        budget = left if k == len(tries) - 1 else left / 2
        done = k / len(tries)

        def part(f: float, done=done) -> None:
            progress(min(1.0, done + f / len(tries)))

        motion = plan_motion(checker, qs, q_goal, planner=planner, time_limit=budget,
                             seed=seed + k, resolution=resolution, limits=rates,
                             progress=part)
        if motion.success or motion.status in (MotionStatus.START_IN_COLLISION,
                                               MotionStatus.OUT_OF_LIMITS):
            break
    if motion is None:
        return None, "no time left for the joint-space search"
    if motion.success:
        return motion, ""
    tried = "" if len(tries) == 1 else f" ({len(tries)} goal configurations tried)"
    return motion, f"{motion.message}{tried}"


def joint_samples(model: RobotModel, path: np.ndarray, spacing: float,
                  joint_step: float = SAMPLE_JOINT_STEP) -> tuple[np.ndarray, np.ndarray]:
    """States ``(S, dof)`` along the straight segments of the joint path ``(K, dof)``, every
    waypoint included, close enough that the tool point moves at most ``spacing`` mm and no
    joint more than ``joint_step`` (rad; x 100 mm for prismatic joints) between neighbours;
    and their tool points ``(S, 3)`` mm."""
    w = np.where(model.revolute, 1.0, 1.0 / PRISMATIC_STEP)
    Qs, Ps = [path[:1]], [fk(model, path[:1])[:, :3, 3]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, math.ceil(float(np.max(np.abs(b - a) * w)) / joint_step))
        while True:
            s = np.arange(1, n + 1) / n
            Q = a + s[:, None] * (b - a)
            Q[-1] = b  # the waypoint itself, not a rounding of it
            P = fk(model, Q)[:, :3, 3]
            steps = np.linalg.norm(np.diff(np.vstack([Ps[-1][-1:], P]), axis=0), axis=1)
            worst = float(steps.max())
            if worst <= spacing or n > 1_000_000:
                break
            n = math.ceil(n * worst / spacing * 1.1) + 1
        Qs.append(Q)
        Ps.append(P)
    return np.vstack(Qs), np.vstack(Ps)


def _joint_result(model, scene, objects, radii, motion, spacing, timing, duration, reason,
                  runtime) -> ArmPathResult:
    """The joint-space motion in ``ArmPathResult``'s shape."""
    Q, P = joint_samples(model, motion.path, spacing)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    clear_tool = scene.path_clearance(P) if scene.obstacles else math.inf
    if objects is None:  # the obstacles themselves: exact capsule distances, as tool paths
        arm_min = float(arm_clearance(model, scene, Q, radii).min()) if scene.obstacles \
            else math.inf
    else:  # a stored scene's shapes: the least over up to 200 states (capped at 1 m)
        obstacles_only = _checker(model, scene, objects, radii, self_collision=False)
        arm_min = obstacles_only.clearance(motion.path, most=200) \
            if obstacles_only.scene is not None else None
    traj = motion.trajectory
    if traj is not None and timing == "uniform":
        traj = traj.scaled(duration / traj.duration)
    cyl, cyl_ok = _cylinders(model, Q, traj)
    why = f" ({reason})" if reason else ""
    message = (f"joint-space motion{why}: {len(motion.path)} joint waypoints, every state "
               f"clear of the obstacles and of the arm itself")
    tool = PathResult(P, float(s[-1]), clear_tool, runtime, np.empty(0), motion.planner,
                      int(motion.stats.get("checks", 0)), PlanStatus.OK, message)
    extra = {"waypoints": motion.path.tolist(),
             "joint_length": motion.length,
             "motion_planning_time_s": motion.planning_time_s,
             "motion_min_clearance": motion.min_clearance,
             "tool_space_failure": reason or None}
    if motion.trajectory is None:
        extra["trajectory_note"] = motion.stats.get("trajectory", "not timed")
    status, msg = PlanStatus.OK, message
    if cyl_ok is False:
        status, msg = PlanStatus.OUT_OF_LIMITS, message + "; but a cylinder leaves its stroke"
    return ArmPathResult(
        tool=tool, points=P, s=s, q=Q, trajectory=traj, cylinders=cyl,
        cylinders_within_stroke=cyl_ok,
        arm_min_clearance=math.inf if arm_min is None else float(arm_min),
        status=status, message=msg, extra=extra, planner="joint_space")


def _cylinders(model: RobotModel, Q: np.ndarray, traj) -> tuple[dict | None, bool | None]:
    """Cylinder lengths at the samples (mm, by name) and whether they and the trajectory's
    (on a grid of 400) stay within stroke; None for a robot without cylinders."""
    try:
        cs = CylinderSet.from_model(model)
    except CylinderError:
        return None, None
    lengths = cs.lengths(Q)
    ok = all(np.all(v) for v in cs.within_stroke(lengths).values())
    if traj is not None:
        Qt = traj.evaluate(np.linspace(0.0, traj.duration, 400))
        ok = ok and all(np.all(v) for v in cs.within_stroke(cs.lengths(Qt), tol=1e-6).values())
    return lengths, bool(ok)
