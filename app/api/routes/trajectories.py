"""Joint trajectories: plan, sample, check, fit to limits (uniformly or time-optimally, with
the robot's cylinder speeds and pump flow), plot; jerk-limited point-to-point moves;
Cartesian lines and ellipses."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from fastapi import APIRouter, Request, Response
from starlette.concurrency import run_in_threadpool

from kinematics.cylinders import CylinderError, cylinder_set
from kinematics.errors import FieldError
from kinematics.fk import fk
from kinematics.model import RobotModel
from planning import Limits, Trajectory, plan_trajectory
from planning.trajectories.cartesian import (
    ellipse_points,
    follow_path,
    line_points,
    path_deviation,
)
from planning.trajectories.hydraulic import HydraulicLimits, hydraulic_limits
from planning.trajectories.joint_path import JointPath
from planning.trajectories.limits_check import (
    binding,
    hydraulic_peaks,
    limit_ratios,
    piece_samples,
)
from planning.trajectories.p2p import jerk_limited
from planning.trajectories.time_scaling import fit_optimal, fit_uniform, path_for

from ...compute import encode_json
from ...plots import trajectory_png
from ...responses import FastJSONRoute
from ..deps import RegistryDep
from ..errors import http_error
from ..trajectory_schemas import (
    MAX_TRAJECTORY_SAMPLES,
    CartesianRequest,
    PlotRequest,
    TrajectoryRequest,
    default_grid,
)

router = APIRouter(prefix="/trajectories", tags=["trajectories"],
                   route_class=FastJSONRoute)

# Checks here are those of the request's shape; planning's own checks (durations, rates,
# waypoints, time scaling, the Cartesian path) raise ``FieldError`` naming the body field,
# answered 422 there by the service's handler, from a worker process too.


def _robot(registry, robot_id: str | None) -> RobotModel | None:
    if robot_id is None:
        return None
    try:
        robot = registry.get(robot_id)
    except KeyError:
        raise http_error(404, ["body", "robot"], f"unknown robot '{robot_id}'",
                         "not_found") from None
    fault = _cylinder_fault(robot)
    if fault is not None:
        raise http_error(409, ["body", "robot"], fault, "conflict")
    return robot


@lru_cache(maxsize=64)
def _cylinder_fault(robot: RobotModel) -> str | None:
    """Why the robot's cylinder data cannot serve a trajectory, None if it can. POST /robots
    refuses such data, but a robot stored before it did may have it: its cylinder speeds
    and pump flow would be NaN wherever a linkage cannot close. (Models are immutable and
    kept by the registry, so once per robot.)"""
    if not {"cylinders", "pump_flow", "pump_cylinders"} & set(robot.extras):
        return None
    try:
        cylinder_set(robot).check_mechanisms()
    except CylinderError as exc:
        return f"robot '{robot.id}' has invalid cylinder data: {exc}"
    return None


def _non_finite(value, path: str = "") -> tuple[str, float] | None:
    """The first number in nested lists and dicts that is NaN or infinite, with its path
    (``hydraulics.cylinders.boom.peak_extension_speed``); None if all are finite."""
    if isinstance(value, float):
        return None if math.isfinite(value) else (path, value)
    items = value.items() if isinstance(value, dict) else \
        enumerate(value) if isinstance(value, list | tuple) else ()
    for key, item in items:
        sub = f"{path}[{key}]" if isinstance(key, int) else f"{path}.{key}" if path else key
        found = _non_finite(item, sub)
        if found is not None:
            return found
    return None


def _encoded(answer: dict, robot: RobotModel | None) -> bytes:
    """The answer as JSON. A NaN or infinity in it is numerics the checks before should have
    refused (data stored before a check existed, say): a 422 saying where, never a 500."""
    try:
        return encode_json(answer)
    except ValueError:  # json's "Out of range float values are not JSON compliant"
        found = _non_finite(answer)
        if found is None:
            raise
    where, value = found
    if robot is not None:
        raise FieldError(["robot"], f"robot '{robot.id}' cannot be evaluated along this "
                         f"trajectory: the answer's {where} came out {value}, not a finite "
                         "number")
    raise FieldError(["waypoints"], "these waypoints give no trajectory in finite numbers: "
                     f"the answer's {where} came out {value}")


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


def _limits(body: TrajectoryRequest | CartesianRequest, robot: RobotModel | None,
            dof: int) -> Limits:
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


def _scaling(value: bool | str) -> str:
    """The request's ``time_scaling`` by name: false is 'none', true 'uniform'."""
    if isinstance(value, bool):
        return "uniform" if value else "none"
    return value


def _check_rows(rows: list[list[float]], dof: int, field: str) -> None:
    for k, row in enumerate(rows):
        if len(row) != dof:
            raise FieldError([field, k], f"expected {dof} joint values, got {len(row)}")


@dataclass
class _Planned:
    """A planned trajectory with the limits it is checked against and how it was timed."""

    traj: Trajectory
    limits: Limits
    robot: RobotModel | None
    hydraulics: HydraulicLimits | None
    timing: dict = field(default_factory=dict)


def _chord_durations(waypoints: list[list[float]]) -> list[float]:
    """Segment durations proportional to joint-space length (1 s per unit; a segment that
    does not move gets the shortest), for paths whose timing is replaced anyway."""
    q = np.asarray(waypoints, dtype=float)
    step = np.linalg.norm(np.diff(q, axis=0), axis=1)
    floor = max(float(step.max(initial=0.0)) * 1e-3, 1e-3)
    return np.maximum(step, floor).tolist()


def _timed(traj: Trajectory, scaling: str, limits: Limits, hydraulics, grid: int | None,
           per_segment: bool, path: JointPath) -> tuple[Trajectory, dict]:
    """``traj`` timed by ``scaling`` ('none', 'uniform', 'optimal': ``path`` re-timed);
    what was done."""
    timing: dict = {"time_scaling": scaling}
    if scaling == "uniform":
        traj = fit_uniform(traj, limits, hydraulics, per_segment=per_segment)
    elif scaling == "optimal":
        res = fit_optimal(path, limits, hydraulics,
                          grid=grid or default_grid(len(path.waypoint_s)))
        if not res.success:
            raise FieldError(["limits"], f"optimal time scaling found no motion: {res.message}")
        traj = res.trajectory
        timing["optimal"] = {
            "grid": len(res.s) - 1,
            "duration_at_grid": res.optimal_duration,
            "stretch": res.stretch,
            "smoothing_window": res.smoothing_window,
            "message": res.message,
        }
    return traj, timing


def _plan(body: TrajectoryRequest, robot: RobotModel | None) -> _Planned:
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
    hydraulics = hydraulic_limits(robot, body.limits.pump_flow if body.limits else None)
    scaling = _scaling(body.time_scaling)
    if body.profile == "jerk_limited":
        return _point_to_point(body, robot, dof, limits, hydraulics)
    if body.end_velocity is not None:
        raise FieldError(["end_velocity"], "end_velocity: only with profile 'jerk_limited'")
    durations = body.durations
    if durations is None:
        if scaling != "optimal":
            raise FieldError(["durations"], "durations: needed unless time_scaling is "
                             "'optimal' or profile is 'jerk_limited'")
        durations = _chord_durations(body.waypoints)
    # Durations (one per segment, each positive) are planning's to check.
    try:
        traj = plan_trajectory(body.method, body.waypoints, durations,
                               body.velocities, body.accelerations)
        rests = body.velocities is None and body.accelerations is None
        path = path_for(body.method, body.waypoints, traj, rests=rests) \
            if scaling == "optimal" else None
        traj, timing = _timed(traj, scaling, limits, hydraulics, body.grid,
                              traj.method == "quintic" and rests, path)
    except FieldError:
        raise
    except ValueError as exc:  # numerics that found no trajectory through these waypoints
        raise FieldError(["waypoints"], str(exc)) from None
    _check_samples(traj, body.dt)
    return _Planned(traj, limits, robot, hydraulics, timing | {"profile": "path"})


def _point_to_point(body: TrajectoryRequest, robot: RobotModel | None, dof: int,
                    limits: Limits, hydraulics) -> _Planned:
    if len(body.waypoints) != 2:
        raise FieldError(["waypoints"], "waypoints: a jerk_limited profile goes from the first "
                         f"waypoint to the second: exactly 2, got {len(body.waypoints)}")
    if body.end_velocity is not None and len(body.end_velocity) != dof:
        raise FieldError(["end_velocity"], f"expected {dof} joint values, got "
                         f"{len(body.end_velocity)}")
    move = jerk_limited(body.waypoints[0], body.waypoints[1], limits, body.end_velocity,
                        hydraulics)
    _check_samples(move.trajectory, body.dt)
    names = [j.name for j in robot.joints] if robot else [f"j{i + 1}" for i in range(dof)]
    return _Planned(move.trajectory, limits, robot, hydraulics, {
        "profile": "jerk_limited", "time_scaling": "none",
        "joint_durations": move.joint_durations.tolist(),
        "limiting_joint": names[move.limiting_joint]})


def _check_samples(traj: Trajectory, dt: float) -> None:
    n = math.floor(traj.duration / dt + 1e-9) + 2
    if n > MAX_TRAJECTORY_SAMPLES:
        raise FieldError(["dt"], f"dt = {dt} s over {traj.duration:.6g} s gives about "
                         f"{n} samples; at most {MAX_TRAJECTORY_SAMPLES}: use a larger dt")


def _joint_names(robot: RobotModel | None, dof: int) -> list[str]:
    return [j.name for j in robot.joints] if robot else [f"j{i + 1}" for i in range(dof)]


def _hydraulic_violations(traj: Trajectory, hydraulics: HydraulicLimits) -> list[dict]:
    """Cylinder speeds and pump flow over their limits, searched like the joints' peaks."""
    t, q, qd = piece_samples(traj)
    r = limit_ratios(q, qd, qd, None, None, None, None, hydraulics)
    out = []
    for c, name in enumerate(hydraulics.names):
        k = int(np.argmax(r.cylinder[:, c])) if len(t) else 0
        if r.cylinder[k, c] > 1 + 1e-9:
            v = float(r.speeds[k, c])
            extending = v > 0
            lim = hydraulics.max_extension[c] if extending else hydraulics.max_retraction[c]
            out.append({"joint": None, "name": name,
                        "quantity": "extension" if extending else "retraction",
                        "value": abs(v), "limit": float(lim), "t": float(t[k])})
    if hydraulics.has_pump and len(t):
        k = int(np.argmax(r.pump))
        if r.pump[k] > 1 + 1e-9:
            lpm = 60.0 / 1e6
            out.append({"joint": None, "name": "pump", "quantity": "flow",
                        "value": float(r.flow[k]) * lpm,
                        "limit": float(hydraulics.pump_flow) * lpm, "t": float(t[k])})
    return out


def _report(planned: _Planned, dt: float) -> dict:
    traj, limits, robot, hydraulics = (planned.traj, planned.limits, planned.robot,
                                       planned.hydraulics)
    samples = traj.sample(dt)
    names = _joint_names(robot, traj.dof)
    violations = [
        {"joint": v.joint, "name": names[v.joint], "quantity": v.quantity, "value": v.value,
         "limit": v.limit, "t": v.t}
        for v in traj.violations(limits)
    ]
    if hydraulics is not None:
        violations += _hydraulic_violations(traj, hydraulics)
    ratios = limit_ratios(samples.q, samples.qd, samples.qdd, samples.qddd, limits.velocity,
                          limits.acceleration, limits.jerk, hydraulics)
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
        "binding": binding(ratios, names, hydraulics),
        "hydraulics": hydraulic_peaks(ratios, hydraulics) if hydraulics is not None else None,
        "timing": planned.timing,
    }


#: Above this many samples (or waypoints) a trajectory is computed in a worker process.
HEAVY_SAMPLES = 5_000
HEAVY_WAYPOINTS = 100


def _heavy(body: TrajectoryRequest) -> bool:
    samples = sum(body.durations) / body.dt if body.durations else 0.0
    return samples > HEAVY_SAMPLES or len(body.waypoints) > HEAVY_WAYPOINTS or \
        _scaling(body.time_scaling) != "none" or body.profile != "path"


async def _computed(request: Request, heavy: bool, fn, *args) -> bytes:
    """``fn(*args)`` on the compute pool (a ``FieldError`` it raises answers 422 naming its
    field)."""
    return await request.app.state.compute.run(heavy, fn, *args)


def _plan_answer(body: TrajectoryRequest, robot: RobotModel | None) -> bytes:
    return _encoded(_report(_plan(body, robot), body.dt), robot)


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
    planned = _plan(body, robot)
    traj = planned.traj
    samples = traj.sample(body.dt)
    names = _joint_names(robot, traj.dof)
    units = [("rad" if j.revolute else "mm") for j in robot.joints] if robot is not None \
        else ["rad"] * traj.dof
    hydraulic = None
    h = planned.hydraulics
    if h is not None:
        speeds = h.speeds(samples.q, samples.qd)
        hydraulic = {
            "names": list(h.names), "speeds": speeds,
            "max_extension": h.max_extension, "max_retraction": h.max_retraction,
            "flow": h.flow(speeds) * 60.0 / 1e6 if np.any(h.piston > 0) else None,
            "pump_flow": h.pump_flow * 60.0 / 1e6 if h.has_pump else None,
        }
    return trajectory_png(samples, names, units, body.title or f"{traj.method} trajectory",
                          traj.breaks[traj.waypoint_index], hydraulic=hydraulic)


#: Above this many path points a Cartesian request is computed in a worker process.
HEAVY_POINTS = 20


@router.post("/cartesian")
async def cartesian(body: CartesianRequest, registry: RegistryDep,
                    request: Request) -> Response:
    """A straight line or an ellipse for the tool, mapped through IK into a joint trajectory,
    with how closely the tool follows the path."""
    robot = await run_in_threadpool(_robot, registry, body.robot)
    heavy = body.points > HEAVY_POINTS or body.duration / body.dt > HEAVY_SAMPLES or \
        _scaling(body.time_scaling) != "none"
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
    limits = _limits(body, robot, robot.dof)
    hydraulics = hydraulic_limits(robot, body.limits.pump_flow if body.limits else None)
    scaling = _scaling(body.time_scaling)
    path = JointPath.through(result.q_waypoints) if scaling == "optimal" else None
    traj, timing = _timed(result.trajectory, scaling, limits, hydraulics, body.grid, False, path)
    _check_samples(traj, body.dt)
    out = _report(_Planned(traj, limits, robot, hydraulics, timing | {"profile": "path"}),
                  body.dt)
    out["points"] = result.points.tolist()
    out["waypoints_q"] = result.q_waypoints.tolist()
    dev_max, dev_mean = (result.max_deviation, result.mean_deviation) \
        if traj is result.trajectory else path_deviation(robot, traj, result.points)
    out["tracking"] = {
        "max_deviation": dev_max,
        "mean_deviation": dev_mean,
        "max_waypoint_error": float(result.waypoint_error.max()),
    }
    return _encoded(out, robot)
