"""The status family: one base for every enum that says how a solver's or planner's run ended.

``kinematics.ik.IKStatus``, ``planning.status.PlanStatus``, ``planning.motion.MotionStatus``
and ``planning.trajectories.topp.ToppStatus`` all extend ``Status``. Each keeps the values its
results report (the strings the API emits), but every value is drawn from one vocabulary,
``STATUS_VALUES``, so that a word means one thing wherever it appears: ``no_path`` is the
same outcome for a tool path and for a joint-space motion, ``out_of_limits`` the same for IK
and for a planned move. A value shared by two enums compares equal across them (they are
strings): ``IKStatus.OK == PlanStatus.OK``.

``Status`` has no members itself (an enum with members cannot be extended); it carries what
every status shares: ``succeeded`` (the value is ``ok``) and ``meaning`` (the vocabulary's
description of the value). A result's ``success`` is derived from its status.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["Status", "STATUS_VALUES", "OK"]

#: The value every status family member uses for a run that succeeded.
OK = "ok"

#: Every value a status may take, with what it means. A new status value is added here
#: first, with its meaning, before an enum uses it.
STATUS_VALUES: dict[str, str] = {
    OK: "the run succeeded: its answer passed every check",
    # IK
    "unreachable": "no configuration puts the tool on the pose or point, limits aside",
    "out_of_limits": "the answer exists only outside a joint's limits or a cylinder's stroke",
    "not_converged": "the numeric search found nothing within tolerance",
    # searches and planners
    "no_path": "the search ended without connecting start and goal in the free space it saw",
    "budget_spent": "the iteration, sample or evaluation budget ran out before the goal",
    "timeout": "the time limit ran out before a path was found",
    "collision": "the best answer found hits an obstacle, another arm or the robot itself",
    "invalid_input": "a start or goal the planner cannot begin from as given",
    "start_in_collision": "the start configuration is in collision",
    "goal_in_collision": "the goal configuration (every one of them) is in collision",
    "goal_unreachable": "no configuration reaches the goal pose",
    # constrained motion
    "start_violates_constraint": "the start configuration is outside a path constraint's "
                                 "tolerance",
    "goal_violates_constraint": "the goal configuration is outside a path constraint's "
                                "tolerance",
    # paths followed step by step (Cartesian segments)
    "discontinuous": "the joint path would jump (an IK branch change, a flip near a singular "
                     "configuration)",
    # time parameterisation
    "infeasible": "no timing keeps the limits (e.g. a start or end speed that is too high)",
    "unbounded": "somewhere no limit bounds the path speed (a joint without any limit)",
}


class Status(StrEnum):
    """Base of every status enum (module docstring): members are strings from
    ``STATUS_VALUES``."""

    @property
    def succeeded(self) -> bool:
        """True when the run succeeded (the value is ``ok``)."""
        return self.value == OK

    @property
    def meaning(self) -> str:
        """What the value means, from ``STATUS_VALUES``."""
        return STATUS_VALUES[self.value]
