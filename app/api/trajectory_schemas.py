"""Bodies of the trajectory endpoints (units: rad or mm per joint, s)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import ConfigDict, Field

from ..fields import (
    Coordinate,
    Direction3,
    Duration,
    JointValue,
    Point3,
    Rate,
    bounded_list,
    joint_batch,
    pose_type,
)
from .schemas import Body, body_examples

__all__ = [
    "DEFAULT_GRID",
    "MAX_GRID",
    "default_grid",
    "MAX_TRAJECTORY_SAMPLES",
    "RateLimits",
    "TrajectoryRequest",
    "PlotRequest",
    "LinePath",
    "EllipsePath",
    "CartesianRequest",
]

#: Most samples one trajectory answer carries (422 above; raise dt).
MAX_TRAJECTORY_SAMPLES = 50_000
#: Most waypoints of one trajectory.
MAX_WAYPOINTS = 1_000
#: Largest joint rate given at a waypoint (rad/s or mm/s, and per s² for accelerations).
MAX_WAYPOINT_RATE = 1e6

PerJoint = bounded_list(Rate, 32, min_length=1) | Rate
WaypointRate = Annotated[float, Field(ge=-MAX_WAYPOINT_RATE, le=MAX_WAYPOINT_RATE)]
WaypointRates = bounded_list(bounded_list(WaypointRate, 32, min_length=1), MAX_WAYPOINTS)
Step = Annotated[float, Field(ge=1e-6, le=3600.0, description="Sampling step, s")]


#: Grid intervals of optimal time scaling: at least DEFAULT_GRID, GRID_PER_SEGMENT per
#: waypoint segment, at most MAX_GRID (also the most a request may ask for: a jerk-limited
#: profile on 5,000 intervals takes about 6 s here).
DEFAULT_GRID = 500
GRID_PER_SEGMENT = 40
MAX_GRID = 5_000


def default_grid(waypoints: int) -> int:
    """Grid intervals for a path through ``waypoints`` points."""
    return min(max(DEFAULT_GRID, GRID_PER_SEGMENT * (waypoints - 1)), MAX_GRID)


class RateLimits(Body):
    """Rate limits per joint (a list) or for every joint (one number); positive."""

    velocity: PerJoint | None = Field(None, description="rad/s or mm/s")
    acceleration: PerJoint | None = Field(None, description="rad/s² or mm/s²")
    jerk: PerJoint | None = Field(None, description="rad/s³ or mm/s³")
    pump_flow: Rate | None = Field(
        None, description="L/min shared by the robot's cylinders; overrides the robot's "
        "pump_flow (needs cylinders with bore and rod)")


TimeScaling = Annotated[
    bool | Literal["none", "uniform", "optimal"],
    Field(description="none (false): as planned; uniform (true): one factor per trajectory "
          "(per segment for quintic at rest) to the shortest that meets the limits; optimal: "
          "the path re-timed time-optimally (TOPP-RA) within the joint limits, the cylinder "
          "speeds and the pump flow, jerk-limited when limits.jerk is given; needs "
          "limits.acceleration"),
]


class TrajectoryRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"robot": "pile_driver", "time_scaling": "optimal", "limits": {"acceleration": 5.0},
         "waypoints": [[0, 0.1, -0.9, -0.5, 0, 0], [0, 0.9, -0.1, -0.5, 0, 0]], "dt": 0.1},
        {"waypoints": [[0, 0], [1, -0.5], [2, 0]], "durations": [1.0, 1.5],
         "method": "quintic"}))

    method: Literal["quintic", "sextic", "bspline5", "smooth"] = Field(
        "quintic",
        description="quintic: one per segment, at rest at each waypoint unless velocities/"
        "accelerations are given; sextic: through a via point without stopping (3 "
        "waypoints; more use 'smooth'); bspline5: quintic B-spline at rest at both ends; "
        "smooth: C4 quintic spline through all waypoints",
    )
    waypoints: joint_batch(MAX_WAYPOINTS) = Field(
        description=f"Joint waypoints, 2 to {MAX_WAYPOINTS}", min_length=2)
    durations: bounded_list(Duration, MAX_WAYPOINTS - 1, min_length=1) | None = Field(
        None, description="Duration of each segment, s (one fewer than waypoints). Needed "
        "unless time_scaling is 'optimal' or profile is 'jerk_limited' (then it only shapes "
        "the path; default: proportional to each segment's joint-space length)")
    dt: Step = 0.01
    robot: str | None = Field(None, max_length=64,
                              description="Check joint and speed limits of this robot")
    velocities: WaypointRates | None = Field(None, description="quintic: rates at waypoints")
    accelerations: WaypointRates | None = Field(None, description="quintic: at waypoints")
    limits: RateLimits | None = Field(None, description="Rate limits to check (and fit)")
    time_scaling: TimeScaling = False
    grid: int | None = Field(None, ge=10, le=MAX_GRID, description="Grid intervals along the "
                             f"path for optimal time scaling (default {GRID_PER_SEGMENT} per "
                             f"waypoint segment, at least {DEFAULT_GRID}, at most "
                             f"{MAX_GRID})")
    profile: Literal["path", "jerk_limited"] = Field(
        "path", description="path: through the waypoints by 'method'; jerk_limited: from "
        "the first waypoint to the second (exactly two), each joint a 7-segment S-curve within "
        "limits.velocity (or the robot's), acceleration and jerk, all arriving together "
        "(method, durations and time_scaling do not apply)")
    end_velocity: bounded_list(WaypointRate, 32, min_length=1) | None = Field(
        None, description="jerk_limited: joint velocities at the end (default rest)")


class PlotRequest(TrajectoryRequest):
    title: str = Field("", max_length=200)


class LinePath(Body):
    kind: Literal["line"]
    start: Point3 | None = Field(None, description="mm; default the tool position at q0")
    end: Point3 = Field(description="mm")


class EllipsePath(Body):
    kind: Literal["ellipse"]
    center: Point3 = Field(description="mm")
    radii: bounded_list(Coordinate, 2, min_length=2) = Field(description="(a, b) mm")
    normal: Direction3 = [0.0, 0.0, 1.0]
    major: Direction3 | None = Field(None, description="Direction of the first radius")


class CartesianRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"robot": "glt_palletizer", "path": {"kind": "line", "end": [1000, 200, 900]},
         "points": 30, "time_scaling": "optimal",
         "limits": {"velocity": 1.0, "acceleration": 2.0}}))

    robot: str = Field(max_length=64)
    path: Annotated[LinePath | EllipsePath, Field(discriminator="kind")]
    q0: bounded_list(JointValue, 32, min_length=1) | None = Field(
        None, description="Start configuration; default the middle of the joint limits"
    )
    rotation: pose_type(3) | None = Field(
        None, description="Tool orientation (3x3) kept along the path; default that at q0"
    )
    points: int = Field(50, ge=2, le=2000, description="Waypoints along the path")
    duration: Duration = Field(10.0, description="s; with time_scaling 'optimal' the "
                               "duration is the fastest within the limits instead")
    dt: Step = 0.05
    limits: RateLimits | None = Field(None, description="Rate limits to check (and fit)")
    time_scaling: TimeScaling = False
    grid: int | None = Field(None, ge=10, le=MAX_GRID, description="Grid intervals for optimal "
                             f"time scaling (default {GRID_PER_SEGMENT} per path point "
                             f"interval, at least {DEFAULT_GRID}, at most {MAX_GRID})")
