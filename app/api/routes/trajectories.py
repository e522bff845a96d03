"""Joint trajectories: plan, sample, check, fit to limits, plot; Cartesian lines and ellipses."""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter, Request, Response
from starlette.concurrency import run_in_threadpool

from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.model import RobotModel
from planning import Limits, Trajectory, plan_trajectory
from planning.trajectories.cartesian import ellipse_points, follow_path, line_points
from planning.trajectories.time_scaling import fit_to_limits

from ...compute import encode_json
from ...plots import trajectory_png
from ..deps import RegistryDep
from ..errors import http_error
from ..trajectory_schemas import (
    MAX_TRAJECTORY_SAMPLES,
    CartesianRequest,
    PlotRequest,
    TrajectoryRequest,
)

router = APIRouter(prefix="/trajectories", tags=["trajectories"])

# Checks here are those of the request's shape; planning's own checks (durations, rates,
# waypoints, time scaling, the Cartesian path) raise ``FieldError`` naming the body field,
# answered 422 there by the service's handler, from a worker process too.


def _robot(registry, robot_id: str | None) -> RobotModel | None:
    if robot_id is None:
        return None
    try:
        return registry.get(robot_id)
    except KeyError:
        raise http_error(404, ["body", "robot"], f"unknown robot '{robot_id}'",
                         "not_found") from None


def _per_joint(value, dof: int, field: str) -> np.ndarray | None:
    if value is None:
        return None
    arr = np.broadcast_to(np.asarray(value, dtype=float), (dof,)) if np.ndim(value) == 0 \
        else np.asarray(value, dtype=float)
    if arr.shape != (dof,):
        raise FieldError(["limits", field], f"expected one value or {dof} values, got {arr.size}")
    if np.any(arr <= 0):
        raise FieldError(["limits", field], "limits must be positive")
    return arr


def _limits(body: TrajectoryRequest, robot: RobotModel | None, dof: int) -> Limits:
    lim = body.limits
    velocity = _per_joint(lim.velocity if lim else None, dof, "velocity")
    if velocity is None and robot is not None and np.any(np.isfinite(robot.velocity_limits)):
        velocity = np.asarray(robot.velocity_limits)
    return Limits(
        lower=None if robot is None else np.asarray(robot.lower),
        upper=None if robot is None else np.asarray(robot.upper),
        velocity=velocity,
        acceleration=_per_joint(lim.acceleration if lim else None, dof, "acceleration"),
        jerk=_per_joint(lim.jerk if lim else None, dof, "jerk"),
    )


def _check_rows(rows: list[list[float]], dof: int, field: str) -> None:
    for k, row in enumerate(rows):
        if len(row) != dof:
            raise FieldError([field, k], f"expected {dof} joint values, got {len(row)}")


def _plan(body: TrajectoryRequest,
          robot: RobotModel | None) -> tuple[Trajectory, Limits, RobotModel | None]:
    if len(body.waypoints) < 2:
        raise FieldError(["waypoints"], "need at least 2 waypoints")
    dof = robot.dof if robot is not None else len(body.waypoints[0])
    if dof == 0:
        raise FieldError(["waypoints", 0], "a waypoint needs at least one joint value")
    _check_rows(body.waypoints, dof, "waypoints")
    for name in ("velocities", "accelerations"):
        rows = getattr(body, name)
        if rows is not None:
            if body.method != "quintic":
                raise FieldError([name], f"{name}: waypoint rates can only be given with "
                                 "method 'quintic'")
            if len(rows) != len(body.waypoints):
                raise FieldError([name], f"need one row per waypoint ({len(body.waypoints)})")
            _check_rows(rows, dof, name)
    limits = _limits(body, robot, dof)
    # Durations (one per segment, each positive) are planning's to check.
    try:
        traj = plan_trajectory(body.method, body.waypoints, body.durations,
                               body.velocities, body.accelerations)
        if body.time_scaling:
            rests = body.velocities is None and body.accelerations is None
            traj = fit_to_limits(traj, limits, per_segment=traj.method == "quintic" and rests)
    except FieldError:
        raise
    except ValueError as exc:  # numerics that found no trajectory through these waypoints
        raise FieldError(["waypoints"], str(exc)) from None
    n = math.floor(traj.duration / body.dt + 1e-9) + 2
    if n > MAX_TRAJECTORY_SAMPLES:
        raise FieldError(["dt"], f"dt = {body.dt} s over {traj.duration:.6g} s gives about "
                         f"{n} samples; at most {MAX_TRAJECTORY_SAMPLES}: use a larger dt")
    return traj, limits, robot


def _report(traj: Trajectory, limits: Limits, robot: RobotModel | None, dt: float) -> dict:
    samples = traj.sample(dt)
    names = [j.name for j in robot.joints] if robot else [f"j{i + 1}" for i in range(traj.dof)]
    violations = [
        {"joint": v.joint, "name": names[v.joint], "quantity": v.quantity, "value": v.value,
         "limit": v.limit, "t": v.t}
        for v in traj.violations(limits)
    ]
    return {
        "method": traj.method,
        "durations": np.diff(traj.breaks[traj.waypoint_index]).tolist(),
        "duration": traj.duration,
        "t": samples.t.tolist(),
        "q": samples.q.tolist(),
        "qd": samples.qd.tolist(),
        "qdd": samples.qdd.tolist(),
        "qddd": samples.qddd.tolist(),
        "continuity": traj.continuity(),
        "peaks": {name: traj.peaks(m)[0].tolist()
                  for m, name in enumerate(("velocity", "acceleration", "jerk"), start=1)},
        "limits": {"ok": not violations, "violations": violations},
    }


#: Above this many samples (or waypoints) a trajectory is computed in a worker process.
HEAVY_SAMPLES = 5_000
HEAVY_WAYPOINTS = 100


def _heavy(body: TrajectoryRequest) -> bool:
    samples = sum(body.durations) / body.dt
    return samples > HEAVY_SAMPLES or len(body.waypoints) > HEAVY_WAYPOINTS or \
        body.time_scaling


async def _computed(request: Request, heavy: bool, fn, *args) -> bytes:
    """``fn(*args)`` on the compute pool (a ``FieldError`` it raises answers 422 naming its
    field)."""
    return await request.app.state.compute.run(heavy, fn, *args)


def _plan_answer(body: TrajectoryRequest, robot: RobotModel | None) -> bytes:
    traj, limits, robot = _plan(body, robot)
    return encode_json(_report(traj, limits, robot, body.dt))


@router.post("")
async def plan(body: TrajectoryRequest, registry: RegistryDep, request: Request) -> Response:
    """Plan a joint trajectory; sampled q, q̇, q̈, jerk with continuity and limit reports."""
    robot = await run_in_threadpool(_robot, registry, body.robot)
    answer = await _computed(request, _heavy(body), _plan_answer, body, robot)
    return Response(answer, media_type="application/json")


@router.post("/plot", response_class=Response,
             responses={200: {"content": {"image/png": {}}}})
async def plot(body: PlotRequest, registry: RegistryDep, request: Request) -> Response:
    """The same trajectory as a PNG: position, velocity, acceleration and jerk panels."""
    robot = await run_in_threadpool(_robot, registry, body.robot)
    # Drawing holds the interpreter for a while whatever the size: always in a worker.
    png = await _computed(request, True, _plot_answer, body, robot)
    return Response(png, media_type="image/png")


def _plot_answer(body: PlotRequest, robot: RobotModel | None) -> bytes:
    traj, _, robot = _plan(body, robot)
    samples = traj.sample(body.dt)
    if robot is not None:
        names = [j.name for j in robot.joints]
        units = ["rad" if j.revolute else "mm" for j in robot.joints]
    else:
        names = [f"j{i + 1}" for i in range(traj.dof)]
        units = ["rad"] * traj.dof
    return trajectory_png(samples, names, units, body.title or f"{traj.method} trajectory",
                          traj.breaks[traj.waypoint_index])


#: Above this many path points a Cartesian request is computed in a worker process.
HEAVY_POINTS = 20


@router.post("/cartesian")
async def cartesian(body: CartesianRequest, registry: RegistryDep,
                    request: Request) -> Response:
    """A straight line or an ellipse for the tool, mapped through IK into a joint trajectory,
    with how closely the tool follows the path."""
    robot = await run_in_threadpool(_robot, registry, body.robot)
    heavy = body.points > HEAVY_POINTS or body.duration / body.dt > HEAVY_SAMPLES
    answer = await _computed(request, heavy, _cartesian_answer, body, robot)
    return Response(answer, media_type="application/json")


def _cartesian_answer(body: CartesianRequest, robot: RobotModel) -> bytes:
    if body.q0 is not None and len(body.q0) != robot.dof:
        raise FieldError(["q0"], f"expected {robot.dof} joint values, got {len(body.q0)}")
    q0 = np.asarray(body.q0 if body.q0 is not None else robot.mid_configuration(), dtype=float)
    T0 = fk(robot, q0)
    if body.rotation is not None:
        rows = body.rotation
        R = np.asarray(rows, dtype=float) if all(len(r) == 3 for r in rows) else np.zeros(0)
        if R.shape != (3, 3) or np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or \
                np.linalg.det(R) < 0:
            raise FieldError(["rotation"], "must be a 3x3 rotation matrix")
    else:
        R = T0[:3, :3]
    path = body.path
    try:
        if path.kind == "line":
            start = T0[:3, 3] if path.start is None else np.asarray(path.start)
            pts = line_points(start, path.end, body.points)
        else:
            pts = ellipse_points(path.center, path.radii, body.points, normal=path.normal,
                                 major=path.major)
    except FieldError as exc:  # it names a field of the path (or the number of its points)
        raise FieldError(["path", *exc.loc], exc.message) from None
    try:
        result = follow_path(robot, pts, R, body.duration, q0)
    except FieldError:
        raise
    except ValueError as exc:  # a point the tool cannot reach
        raise FieldError(["path"], f"the path cannot be followed: {exc}") from None
    n = math.floor(body.duration / body.dt + 1e-9) + 2
    if n > MAX_TRAJECTORY_SAMPLES:
        raise FieldError(["dt"], f"at most {MAX_TRAJECTORY_SAMPLES} samples: use a larger dt")
    out = _report(result.trajectory, Limits(lower=np.asarray(robot.lower),
                                            upper=np.asarray(robot.upper)), robot, body.dt)
    out["points"] = result.points.tolist()
    out["waypoints_q"] = result.q_waypoints.tolist()
    out["tracking"] = {
        "max_deviation": result.max_deviation,
        "mean_deviation": result.mean_deviation,
        "max_waypoint_error": float(result.waypoint_error.max()),
    }
    return encode_json(out)
