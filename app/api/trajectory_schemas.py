"""Bodies of the trajectory endpoints (units: rad or mm per joint, s)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

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
from .schemas import Body

__all__ = [
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


class RateLimits(Body):
    """Rate limits per joint (a list) or for every joint (one number); positive."""

    velocity: PerJoint | None = Field(None, description="rad/s or mm/s")
    acceleration: PerJoint | None = Field(None, description="rad/s² or mm/s²")
    jerk: PerJoint | None = Field(None, description="rad/s³ or mm/s³")


class TrajectoryRequest(Body):
    method: Literal["quintic", "sextic", "bspline5", "smooth"] = Field(
        "quintic",
        description="quintic: one per segment, at rest at each waypoint unless velocities/"
        "accelerations are given; sextic: through a via point without stopping (3 "
        "waypoints; more use 'smooth'); bspline5: quintic B-spline at rest at both ends; "
        "smooth: C4 quintic spline through all waypoints",
    )
    waypoints: joint_batch(MAX_WAYPOINTS) = Field(
        description=f"Joint waypoints, 2 to {MAX_WAYPOINTS}", min_length=2)
    durations: bounded_list(Duration, MAX_WAYPOINTS - 1, min_length=1) = Field(
        description="Duration of each segment, s (one fewer than waypoints)")
    dt: Step = 0.01
    robot: str | None = Field(None, max_length=64,
                              description="Check joint and speed limits of this robot")
    velocities: WaypointRates | None = Field(None, description="quintic: rates at waypoints")
    accelerations: WaypointRates | None = Field(None, description="quintic: at waypoints")
    limits: RateLimits | None = Field(None, description="Rate limits to check (and fit)")
    time_scaling: bool = Field(
        False,
        description="Rescale the durations to the shortest that respect the rate limits "
        "(robot speed limits and 'limits')",
    )


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
    robot: str = Field(max_length=64)
    path: Annotated[LinePath | EllipsePath, Field(discriminator="kind")]
    q0: bounded_list(JointValue, 32, min_length=1) | None = Field(
        None, description="Start configuration; default the middle of the joint limits"
    )
    rotation: pose_type(3) | None = Field(
        None, description="Tool orientation (3x3) kept along the path; default that at q0"
    )
    points: int = Field(50, ge=2, le=2000, description="Waypoints along the path")
    duration: Duration = 10.0
    dt: Step = 0.05
