"""Motion planning: joint trajectories, obstacle-avoiding paths, drill-hole sequencing,
multi-arm motion and trajectory tracking.

Pure numpy/scipy code: it never imports ``app`` or ``web``. Frames, units and array
layouts: docs/conventions.md. The names below are the public surface; each loads its module
on first use, so ``import planning`` costs nothing until a name is used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .arm_paths import ArmPathResult as ArmPathResult
    from .arm_paths import plan_arm_path as plan_arm_path
    from .bspline import quintic_bspline as quintic_bspline
    from .cartesian import CartesianPlan as CartesianPlan
    from .cartesian import ellipse_points as ellipse_points
    from .cartesian import follow_path as follow_path
    from .cartesian import line_points as line_points
    from .drilling import FacePattern as FacePattern
    from .drilling import FacePlan as FacePlan
    from .drilling import allocate_holes as allocate_holes
    from .drilling import face_pattern as face_pattern
    from .drilling import plan_face as plan_face
    from .path_compare import compare_planners as compare_planners
    from .paths import PathResult as PathResult
    from .paths import path_length as path_length
    from .paths import plan_path as plan_path
    from .polynomials import quintic_segments as quintic_segments
    from .polynomials import sextic_via as sextic_via
    from .polynomials import smooth_spline as smooth_spline
    from .registry import Algorithm as Algorithm
    from .registry import Knob as Knob
    from .registry import algorithm_classes as algorithm_classes
    from .registry import algorithm_names as algorithm_names
    from .registry import knobs as knobs
    from .registry import make as make
    from .registry import register as register
    from .scene import Box as Box
    from .scene import Capsule as Capsule
    from .scene import Scene as Scene
    from .scene import Sphere as Sphere
    from .sequencing import SequenceResult as SequenceResult
    from .sequencing import sequence_holes as sequence_holes
    from .status import PlanStatus as PlanStatus
    from .time_scaling import fit_to_limits as fit_to_limits
    from .tracking import EllipseTask as EllipseTask
    from .tracking import LineTask as LineTask
    from .tracking import PIGains as PIGains
    from .tracking import TrackingConfig as TrackingConfig
    from .tracking import TrackingResult as TrackingResult
    from .tracking import TuningResult as TuningResult
    from .tracking import simulate as simulate
    from .tracking import tune_gains as tune_gains
    from .tracking_stats import TrackingTable as TrackingTable
    from .tracking_stats import format_table3 as format_table3
    from .tracking_stats import tracking_table as tracking_table
    from .trajectory import Limits as Limits
    from .trajectory import Samples as Samples
    from .trajectory import Trajectory as Trajectory
    from .trajectory import Violation as Violation

#: Every public name but those defined here: name -> module it loads from on first use.
_LAZY = {
    "ArmPathResult": "arm_paths",
    "plan_arm_path": "arm_paths",
    "quintic_bspline": "bspline",
    "CartesianPlan": "cartesian",
    "ellipse_points": "cartesian",
    "follow_path": "cartesian",
    "line_points": "cartesian",
    "FacePattern": "drilling",
    "FacePlan": "drilling",
    "allocate_holes": "drilling",
    "face_pattern": "drilling",
    "plan_face": "drilling",
    "compare_planners": "path_compare",
    "PathResult": "paths",
    "path_length": "paths",
    "plan_path": "paths",
    "quintic_segments": "polynomials",
    "sextic_via": "polynomials",
    "smooth_spline": "polynomials",
    "Algorithm": "registry",
    "Knob": "registry",
    "algorithm_classes": "registry",
    "algorithm_names": "registry",
    "knobs": "registry",
    "make": "registry",
    "register": "registry",
    "Box": "scene",
    "Capsule": "scene",
    "Scene": "scene",
    "Sphere": "scene",
    "SequenceResult": "sequencing",
    "sequence_holes": "sequencing",
    "PlanStatus": "status",
    "fit_to_limits": "time_scaling",
    "EllipseTask": "tracking",
    "LineTask": "tracking",
    "PIGains": "tracking",
    "TrackingConfig": "tracking",
    "TrackingResult": "tracking",
    "TuningResult": "tracking",
    "simulate": "tracking",
    "tune_gains": "tracking",
    "TrackingTable": "tracking_stats",
    "format_table3": "tracking_stats",
    "tracking_table": "tracking_stats",
    "Limits": "trajectory",
    "Samples": "trajectory",
    "Trajectory": "trajectory",
    "Violation": "trajectory",
}

__all__ = [
    "Algorithm",
    "ArmPathResult",
    "Box",
    "Capsule",
    "CartesianPlan",
    "EllipseTask",
    "FacePattern",
    "FacePlan",
    "Knob",
    "Limits",
    "LineTask",
    "PIGains",
    "PathResult",
    "PlanStatus",
    "Samples",
    "Scene",
    "SequenceResult",
    "Sphere",
    "TRAJECTORY_METHODS",
    "TrackingConfig",
    "TrackingResult",
    "TrackingTable",
    "Trajectory",
    "TuningResult",
    "Violation",
    "algorithm_classes",
    "algorithm_names",
    "allocate_holes",
    "compare_planners",
    "ellipse_points",
    "face_pattern",
    "fit_to_limits",
    "follow_path",
    "format_table3",
    "knobs",
    "line_points",
    "make",
    "path_length",
    "plan_arm_path",
    "plan_face",
    "plan_path",
    "plan_trajectory",
    "quintic_bspline",
    "quintic_segments",
    "register",
    "sequence_holes",
    "sextic_via",
    "simulate",
    "smooth_spline",
    "tracking_table",
    "tune_gains",
]

TRAJECTORY_METHODS = ("quintic", "sextic", "bspline5", "smooth")


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


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
    from .bspline import quintic_bspline
    from .polynomials import quintic_segments, sextic_via, smooth_spline

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
