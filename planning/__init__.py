"""Motion planning: joint trajectories, obstacle-avoiding paths, drill-hole sequencing,
multi-arm motion and trajectory tracking.

* ``trajectories``: joint trajectories through waypoints (``plan_trajectory``), time scaling,
  Cartesian lines and ellipses;
* ``paths``: the scene and its obstacles, tool paths (``plan_path``) and arm paths;
* ``optimisers``: the metaheuristics behind one interface;
* ``sequencing``: the drilling order of a face's holes (and the face's hole patterns);
* ``search``: the sampling-based search core (RRT-Connect, RRT*, shortcutting over an
  abstract space) every sampling planner runs on;
* ``motion``: joint-space motion of any arm (and an arm's move to a tool point);
* ``drilling``: tunnel-face drilling with a multi-arm jumbo;
* ``tracking``: tool-path tracking by a PI law and its gain tuners;
* ``registry``, ``budget``, ``status``: what they all share (algorithms by name, evaluation
  budgets, the planners' status, one family with ``kinematics.status``).

Floors, bottom first (a module imports only from its own floor or below, with no circle):
status, budget, registry; search; geometry; collision; trajectories; optimisers and
sequencing; paths; motion; drilling; tracking.

Pure numpy/scipy code: it never imports ``app`` or ``web``. Frames, units and array
layouts: docs/conventions.md. The names below are the public surface; each loads its module
on first use, so ``import planning`` costs nothing until a name is used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

from . import catalog  # noqa: F401 - registers the built-in algorithms by name

if TYPE_CHECKING:
    from .drilling import FacePattern as FacePattern
    from .drilling import FacePlan as FacePlan
    from .drilling import allocate_holes as allocate_holes
    from .drilling import face_pattern as face_pattern
    from .drilling import plan_face as plan_face
    from .paths.arm import ArmPathResult as ArmPathResult
    from .paths.arm import plan_arm_path as plan_arm_path
    from .paths.compare import compare_planners as compare_planners
    from .paths.encoding import path_length as path_length
    from .paths.planners import PathResult as PathResult
    from .paths.planners import plan_path as plan_path
    from .paths.scene import Box as Box
    from .paths.scene import Capsule as Capsule
    from .paths.scene import Scene as Scene
    from .paths.scene import Sphere as Sphere
    from .registry import Algorithm as Algorithm
    from .registry import Knob as Knob
    from .registry import algorithm_classes as algorithm_classes
    from .registry import algorithm_names as algorithm_names
    from .registry import knobs as knobs
    from .registry import make as make
    from .registry import register as register
    from .sequencing import SequenceResult as SequenceResult
    from .sequencing import sequence_holes as sequence_holes
    from .status import PlanStatus as PlanStatus
    from .tracking.simulator import EllipseTask as EllipseTask
    from .tracking.simulator import LineTask as LineTask
    from .tracking.simulator import PIGains as PIGains
    from .tracking.simulator import TrackingConfig as TrackingConfig
    from .tracking.simulator import TrackingResult as TrackingResult
    from .tracking.simulator import simulate as simulate
    from .tracking.stats import TrackingTable as TrackingTable
    from .tracking.stats import format_table3 as format_table3
    from .tracking.stats import tracking_table as tracking_table
    from .tracking.tuning import TuningResult as TuningResult
    from .tracking.tuning import tune_gains as tune_gains
    from .trajectories.bspline import quintic_bspline as quintic_bspline
    from .trajectories.cartesian import CartesianPlan as CartesianPlan
    from .trajectories.cartesian import ellipse_points as ellipse_points
    from .trajectories.cartesian import follow_path as follow_path
    from .trajectories.cartesian import line_points as line_points
    from .trajectories.plan import TRAJECTORY_METHODS as TRAJECTORY_METHODS
    from .trajectories.plan import plan_trajectory as plan_trajectory
    from .trajectories.polynomials import quintic_segments as quintic_segments
    from .trajectories.polynomials import sextic_via as sextic_via
    from .trajectories.polynomials import smooth_spline as smooth_spline
    from .trajectories.time_scaling import fit_to_limits as fit_to_limits
    from .trajectories.trajectory import Limits as Limits
    from .trajectories.trajectory import Samples as Samples
    from .trajectories.trajectory import Trajectory as Trajectory
    from .trajectories.trajectory import Violation as Violation

#: Every public name: name -> the module it loads from on first use.
_LAZY = {
    "ArmPathResult": "paths.arm",
    "plan_arm_path": "paths.arm",
    "quintic_bspline": "trajectories.bspline",
    "CartesianPlan": "trajectories.cartesian",
    "ellipse_points": "trajectories.cartesian",
    "follow_path": "trajectories.cartesian",
    "line_points": "trajectories.cartesian",
    "FacePattern": "drilling",
    "FacePlan": "drilling",
    "allocate_holes": "drilling",
    "face_pattern": "drilling",
    "plan_face": "drilling",
    "compare_planners": "paths.compare",
    "PathResult": "paths.planners",
    "path_length": "paths.encoding",
    "plan_path": "paths.planners",
    "quintic_segments": "trajectories.polynomials",
    "sextic_via": "trajectories.polynomials",
    "smooth_spline": "trajectories.polynomials",
    "Algorithm": "registry",
    "Knob": "registry",
    "algorithm_classes": "registry",
    "algorithm_names": "registry",
    "knobs": "registry",
    "make": "registry",
    "register": "registry",
    "Box": "paths.scene",
    "Capsule": "paths.scene",
    "Scene": "paths.scene",
    "Sphere": "paths.scene",
    "SequenceResult": "sequencing",
    "sequence_holes": "sequencing",
    "PlanStatus": "status",
    "fit_to_limits": "trajectories.time_scaling",
    "EllipseTask": "tracking.simulator",
    "LineTask": "tracking.simulator",
    "PIGains": "tracking.simulator",
    "TrackingConfig": "tracking.simulator",
    "TrackingResult": "tracking.simulator",
    "TuningResult": "tracking.tuning",
    "simulate": "tracking.simulator",
    "tune_gains": "tracking.tuning",
    "TrackingTable": "tracking.stats",
    "format_table3": "tracking.stats",
    "tracking_table": "tracking.stats",
    "Limits": "trajectories.trajectory",
    "Samples": "trajectories.trajectory",
    "Trajectory": "trajectories.trajectory",
    "TRAJECTORY_METHODS": "trajectories.plan",
    "plan_trajectory": "trajectories.plan",
    "Violation": "trajectories.trajectory",
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


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())

