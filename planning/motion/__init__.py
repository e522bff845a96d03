"""Joint-space motion planning: collision-free moves of any arm, from a configuration to a
configuration or a tool pose, checked against the robot's own geometry and a scene.

``MotionChecker`` (compiled, batched validity checks), the searches of ``search``
(RRT-Connect, RRT*, shortcutting) and ``plan_motion``, which validates, searches, simplifies,
times and reports a ``MotionResult``. ``plan_line`` and ``plan_arc`` (``cartesian``) move the
tool along a straight line or an arc, step by step through IK, checked by the same checker.
``arm_motion.plan_arm_motion`` (imported by its module path, so that ``import planning.motion``
loads no path planner) moves an arm to a tool point: the tool path of ``planning.paths.arm``
when the arm can follow it, else a joint-space motion.
"""

from .cartesian import CartesianResult, CartesianStatus, plan_arc, plan_line
from .checker import DEFAULT_RESOLUTION, PRISMATIC_SCALE, PRISMATIC_STEP, MotionChecker
from .constraints import (
    ConstrainedResult,
    ConstrainedStatus,
    parse_constraint,
    parse_constraints,
    plan_constrained,
)
from .planner import (
    MAX_RESOLUTION,
    MAX_TIME_LIMIT,
    MIN_RESOLUTION,
    PLANNERS,
    MotionResult,
    MotionStatus,
    plan_motion,
)
from .warm import start_warm_up, warm_up

__all__ = ["plan_constrained", "parse_constraint", "parse_constraints", "ConstrainedResult",
           "ConstrainedStatus",
           "MotionChecker", "MotionResult", "MotionStatus", "plan_motion", "PLANNERS",
           "DEFAULT_RESOLUTION", "PRISMATIC_SCALE", "PRISMATIC_STEP", "MAX_RESOLUTION",
           "MIN_RESOLUTION", "MAX_TIME_LIMIT", "warm_up", "start_warm_up", "plan_line",
           "plan_arc", "CartesianResult", "CartesianStatus"]
