"""Bodies of the trajectory endpoints (units: rad or mm per joint, s)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from ..fields import Coordinate, Point3
from .schemas import Body, Matrix

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

PerJoint = list[float] | float


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
    waypoints: list[list[float]] = Field(description="Joint waypoints, at least 2")
    durations: list[float] = Field(description="Duration of each segment, s (one fewer)")
    dt: float = Field(0.01, gt=0, description="Sampling step, s")
    robot: str | None = Field(None, description="Check joint and speed limits of this robot")
    velocities: list[list[float]] | None = Field(None, description="quintic: rates at waypoints")
    accelerations: list[list[float]] | None = Field(None, description="quintic: at waypoints")
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
    radii: list[Coordinate] = Field(min_length=2, max_length=2, description="(a, b) mm")
    normal: list[float] = Field([0.0, 0.0, 1.0], min_length=3, max_length=3)
    major: list[float] | None = Field(None, min_length=3, max_length=3,
                                      description="Direction of the first radius")


class CartesianRequest(Body):
    robot: str
    path: Annotated[LinePath | EllipsePath, Field(discriminator="kind")]
    q0: list[float] | None = Field(
        None, description="Start configuration; default the middle of the joint limits"
    )
    rotation: Matrix | None = Field(
        None, description="Tool orientation (3x3) kept along the path; default that at q0"
    )
    points: int = Field(50, ge=2, le=2000, description="Waypoints along the path")
    duration: float = Field(10.0, gt=0, description="s")
    dt: float = Field(0.05, gt=0, description="s")
