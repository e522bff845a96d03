"""How a planner's run ended: one status shared by the results of every planner.

A result's ``success`` is ``status is PlanStatus.OK``; its ``message`` says the same in words
(which obstacle, which joint, how far). ``PlanStatus`` extends ``kinematics.status.Status``,
the base every status enum shares (IK's, joint-space motion's, time parameterisation's), whose
values come from one vocabulary. Invalid input is not a status but an exception: a
``kinematics.errors.FieldError`` naming the field.
"""

from __future__ import annotations

from kinematics.status import Status

__all__ = ["PlanStatus", "Status"]


class PlanStatus(Status):
    """Outcome of a planner's run (a member of the status family, ``kinematics.status``)."""

    #: A plan that passed every check.
    OK = "ok"
    #: The search ended without a path: the free space it saw does not connect start and goal
    #: (a disconnected visibility graph, no ant through, stuck in a local minimum).
    NO_PATH = "no_path"
    #: Its iteration, sample or step budget ran out before it reached the goal.
    BUDGET_SPENT = "budget_spent"
    #: The best path found, the arm along it or the smoothed motion hits an obstacle (or
    #: another arm), or the motion would start or end in a collision.
    COLLISION = "collision"
    #: The arm cannot put its tool on an endpoint or on a point of the way.
    UNREACHABLE = "unreachable"
    #: The motion leaves a joint's limits or a cylinder's stroke.
    OUT_OF_LIMITS = "out_of_limits"
    #: A start or goal the planner cannot begin from as given (e.g. a configuration outside
    #: the joint limits handed to a joint-space planner by another planner).
    INVALID_INPUT = "invalid_input"
