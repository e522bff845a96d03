"""``plan_trajectory``: a joint trajectory through waypoints by one of the named methods."""

from __future__ import annotations

from .bspline import quintic_bspline
from .polynomials import quintic_segments, sextic_via, smooth_spline
from .trajectory import Trajectory

__all__ = ["TRAJECTORY_METHODS", "plan_trajectory"]

TRAJECTORY_METHODS = ("quintic", "sextic", "bspline5", "smooth")


def plan_trajectory(
    method: str, waypoints, durations, velocities=None, accelerations=None
) -> Trajectory:
    """A joint trajectory through ``waypoints (n, dof)`` with segment ``durations (n-1,)`` s.

    * ``quintic``: one quintic per segment, at rest at every waypoint unless ``velocities``/
      ``accelerations (n, dof)`` are given (paper 004 eqs. 18-21);
    * ``sextic``: through a via point without stopping (paper 004 eqs. 22-26); with more
      than three waypoints, where one sextic no longer fits, the C4 ``smooth`` spline;
    * ``bspline5``: quintic B-spline at rest at both ends (paper 002 eqs. 14-18);
    * ``smooth``: C4 quintic spline through every waypoint at rest at both ends.
    """
    if method not in TRAJECTORY_METHODS:
        raise ValueError(f"method: must be one of {', '.join(TRAJECTORY_METHODS)}")
    if method != "quintic" and (velocities is not None or accelerations is not None):
        raise ValueError("velocities: waypoint rates can only be given with method 'quintic'")
    if method == "quintic":
        return quintic_segments(waypoints, durations, velocities, accelerations)
    if method == "sextic":
        if len(waypoints) == 3:
            return sextic_via(waypoints, durations)
        return smooth_spline(waypoints, durations)
    if method == "bspline5":
        return quintic_bspline(waypoints, durations)
    return smooth_spline(waypoints, durations)
