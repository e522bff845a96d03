"""Joint trajectories: how the joints move in time between waypoints.

* ``trajectory``: ``Trajectory`` (piecewise polynomials: sampling, continuity, limit
  checks), ``Limits``, ``Samples``, ``Violation``;
* ``polynomials``: quintic segments, the sextic through a via point, the C4 smooth spline
  (paper 004 section 6);
* ``bspline``: the quintic B-spline through path points (paper 002 section 3.4);
* ``time_scaling``: the shortest durations that keep a trajectory within its rate limits,
  uniformly (one factor) or time-optimally;
* ``joint_path``: geometric joint paths q(s) (a trajectory's shape, a smoothed polyline);
* ``topp``: time-optimal path parameterisation by reachability analysis (TOPP-RA), with a
  jerk smoothing pass (``smoothing``);
* ``hydraulic``: cylinder speed and pump flow limits along a path; ``limits_check``: which
  limit binds at each sample;
* ``p2p``: jerk-limited point-to-point S-curves, all joints arriving together;
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
    from .hydraulic import HydraulicLimits as HydraulicLimits
    from .hydraulic import hydraulic_limits as hydraulic_limits
    from .joint_path import JointPath as JointPath
    from .joint_path import smooth_polyline as smooth_polyline
    from .p2p import PointToPoint as PointToPoint
    from .p2p import jerk_limited as jerk_limited
    from .plan import TRAJECTORY_METHODS as TRAJECTORY_METHODS
    from .plan import plan_trajectory as plan_trajectory
    from .polynomials import quintic_segments as quintic_segments
    from .polynomials import sextic_via as sextic_via
    from .polynomials import smooth_spline as smooth_spline
    from .time_scaling import TIME_SCALINGS as TIME_SCALINGS
    from .time_scaling import fit_optimal as fit_optimal
    from .time_scaling import fit_to_limits as fit_to_limits
    from .time_scaling import fit_uniform as fit_uniform
    from .topp import ToppResult as ToppResult
    from .topp import ToppStatus as ToppStatus
    from .topp import time_optimal as time_optimal
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
    "HydraulicLimits": "hydraulic",
    "hydraulic_limits": "hydraulic",
    "JointPath": "joint_path",
    "smooth_polyline": "joint_path",
    "PointToPoint": "p2p",
    "jerk_limited": "p2p",
    "quintic_segments": "polynomials",
    "sextic_via": "polynomials",
    "smooth_spline": "polynomials",
    "fit_to_limits": "time_scaling",
    "fit_uniform": "time_scaling",
    "fit_optimal": "time_scaling",
    "TIME_SCALINGS": "time_scaling",
    "ToppResult": "topp",
    "ToppStatus": "topp",
    "time_optimal": "topp",
    "Limits": "trajectory",
    "Samples": "trajectory",
    "Trajectory": "trajectory",
    "Violation": "trajectory",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
