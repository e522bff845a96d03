"""Joint trajectories: how the joints move in time between waypoints.

* ``trajectory``: ``Trajectory`` (piecewise polynomials: sampling, continuity, limit
  checks), ``Limits``, ``Samples``, ``Violation``;
* ``polynomials``: quintic segments, the sextic through a via point, the C4 smooth spline
  (paper 004 section 6);
* ``bspline``: the quintic B-spline through path points (paper 002 section 3.4);
* ``time_scaling``: the shortest durations that keep a trajectory within its rate limits;
* ``cartesian``: straight lines and ellipses of the tool mapped through IK into joints;
* ``plan``: ``plan_trajectory``, one of the methods above by name.

The names below load their module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from .bspline import quintic_bspline as quintic_bspline
    from .cartesian import CartesianPlan as CartesianPlan
    from .cartesian import ellipse_points as ellipse_points
    from .cartesian import follow_path as follow_path
    from .cartesian import line_points as line_points
    from .plan import TRAJECTORY_METHODS as TRAJECTORY_METHODS
    from .plan import plan_trajectory as plan_trajectory
    from .polynomials import quintic_segments as quintic_segments
    from .polynomials import sextic_via as sextic_via
    from .polynomials import smooth_spline as smooth_spline
    from .time_scaling import fit_to_limits as fit_to_limits
    from .trajectory import Limits as Limits
    from .trajectory import Samples as Samples
    from .trajectory import Trajectory as Trajectory
    from .trajectory import Violation as Violation

#: Public name -> the module it loads from on first use.
_LAZY = {
    "quintic_bspline": "bspline",
    "CartesianPlan": "cartesian",
    "ellipse_points": "cartesian",
    "follow_path": "cartesian",
    "line_points": "cartesian",
    "TRAJECTORY_METHODS": "plan",
    "plan_trajectory": "plan",
    "quintic_segments": "polynomials",
    "sextic_via": "polynomials",
    "smooth_spline": "polynomials",
    "fit_to_limits": "time_scaling",
    "Limits": "trajectory",
    "Samples": "trajectory",
    "Trajectory": "trajectory",
    "Violation": "trajectory",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
