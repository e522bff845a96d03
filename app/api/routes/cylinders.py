"""Hydraulic cylinders of one robot: joint angles <-> cylinder lengths, pose -> lengths.

A robot without cylinder data answers 409: the request is valid, the robot (as stored now)
cannot serve it, as for an IK method it has not been trained for.
"""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse

from kinematics.cylinders import (
    CylinderError,
    CylinderSet,
    JointLimit,
    LimitCause,
    cylinder_set,
    diagnose_limits,
)
from kinematics.ik import IKStatus, solve_ik
from kinematics.model import RobotModel
from kinematics.numbers import finite_or_none

from ...responses import FastJSONRoute
from ..common import joint_rows
from ..cylinder_schemas import (
    CylindersInverseRequest,
    CylindersInverseResponse,
    CylindersRequest,
    CylindersResponse,
    PoseToCylindersRequest,
    PoseToCylindersResponse,
)
from ..deps import RobotDep
from ..errors import invalid

router = APIRouter(prefix="/robots/{robot_id}", tags=["cylinders"],
                   route_class=FastJSONRoute)


def _cylinders_of(robot: RobotModel) -> CylinderSet:
    """The robot's cylinders, or 409 naming why there are none."""
    if "cylinders" not in robot.extras:
        msg = (
            f"robot '{robot.id}' has no hydraulic cylinders: its model has no 'cylinders' "
            "list (see the built-in 'pile_driver' for the format)"
        )
    else:
        try:
            return cylinder_set(robot)
        except CylinderError as exc:
            msg = f"robot '{robot.id}' has invalid cylinder data: {exc}"
    raise HTTPException(409, detail=[{"loc": ["path", "robot_id"], "msg": msg,
                                      "type": "conflict"}])


def _states(
    robot: RobotModel, cyl: CylinderSet, q: np.ndarray, qd: np.ndarray | None = None
) -> list[dict]:
    """Every cylinder at one configuration ``q (dof,)``; 422 naming ``q`` where the
    mechanism cannot take a joint value (e.g. a linkage that cannot close)."""
    lengths = cyl.lengths(q)
    speeds = cyl.speeds(q, qd) if qd is not None else {}
    out = []
    for name in cyl.names:
        L = float(lengths[name])
        joint = robot.joints[cyl.joint_of(name)]
        v = float(speeds[name]) if name in speeds else None
        if not math.isfinite(L) or (v is not None and not math.isfinite(v)):
            raise invalid(
                ["q"], f"joint '{joint.name}' = {q[cyl.joint_of(name)]:.6g} rad is outside what "
                f"cylinder '{name}''s mechanism can reach (limits {joint.lower:.6g} .. "
                f"{joint.upper:.6g} rad)"
            )
        lo, hi = cyl.limits(name)
        state = {
            "name": name,
            "joint": joint.name,
            "length": L,
            "stroke": L - lo,
            "min_length": lo,
            "max_length": hi,
            "within_limits": bool(cyl.within_stroke({name: L})[name]),
        }
        if v is not None:
            state["speed"] = v
        out.append(state)
    return out


@router.post("/cylinders", response_model=CylindersResponse)
def cylinder_lengths(robot: RobotDep, body: CylindersRequest) -> JSONResponse:
    """Cylinder lengths and strokes (and speeds, given joint speeds) at one configuration."""
    cyl = _cylinders_of(robot)
    q = joint_rows(robot, body.q)[0][0]
    qd = None if body.qd is None else joint_rows(robot, body.qd, "qd")[0][0]
    return JSONResponse({
        "cylinders": _states(robot, cyl, q, qd),
        "joints_within_limits": bool(robot.within_limits(q)),
    })


@router.post("/cylinders/inverse", response_model=CylindersInverseResponse)
def joints_from_cylinders(robot: RobotDep, body: CylindersInverseRequest) -> JSONResponse:
    """Joint values from cylinder lengths; joints without a given cylinder come from q."""
    cyl = _cylinders_of(robot)
    q_other = None if body.q is None else joint_rows(robot, body.q)[0][0]
    # A length out of stroke, an unknown cylinder or a pair that disagrees: CylinderError
    # (a FieldError) at ``lengths.<name>``, answered 422 there.
    q = cyl.joints_from_lengths(body.lengths, q_other)
    return JSONResponse({
        "q": q.tolist(),
        "joints_within_limits": bool(robot.within_limits(q)),
        "cylinders": _states(robot, cyl, q),
    })


#: How each cause of ``kinematics.cylinders.diagnose_limits`` reads in a message.
_CAUSE_TEXT = {
    LimitCause.CANNOT_CLOSE: "which cylinder '{name}''s linkage cannot take",
    LimitCause.BELOW_STROKE: "cylinder '{name}' would be {length:.1f} mm, below its retracted "
                             "{min_length:.1f} mm",
    LimitCause.BEYOND_STROKE: "cylinder '{name}' would be {length:.1f} mm, beyond its extended "
                              "{max_length:.1f} mm",
    LimitCause.JOINT_STOP: "within the stroke of cylinder '{name}' but past the joint stop",
    LimitCause.DEAD_POINT: "past the dead point of cylinder '{name}' (no length of it gives "
                           "this)",
}


def _limit_story(diagnosis: tuple[JointLimit, ...]) -> str:
    """In words: what the nearest out-of-limits solution asks of each joint it violates and
    of the cylinders driving those joints."""
    parts = []
    for d in diagnosis:
        part = (
            f"joint '{d.name}' needs {math.degrees(d.value):.1f} deg (limits "
            f"{math.degrees(d.lower):.1f} .. {math.degrees(d.upper):.1f} deg)"
        )
        for c in d.cylinders:
            part += ", " + _CAUSE_TEXT[c.cause].format(
                name=c.name, length=c.length, min_length=c.min_length, max_length=c.max_length)
        parts.append(part)
    return "; ".join(parts)


@router.post("/pose-to-cylinders", response_model=PoseToCylindersResponse)
def pose_to_cylinders(robot: RobotDep, body: PoseToCylindersRequest) -> JSONResponse:
    """IK of one tool pose, then the cylinder lengths; an unreachable pose says why (200)."""
    cyl = _cylinders_of(robot)
    try:
        T = np.asarray(body.pose, dtype=float)
    except ValueError:
        raise invalid(["pose"], "pose must be a 4x4 matrix") from None
    if T.shape != (4, 4):
        raise invalid(["pose"], f"pose must be a 4x4 matrix, got shape {list(T.shape)}")
    q0 = None if body.q0 is None else joint_rows(robot, body.q0, "q0")[0][0]
    try:
        (r,) = solve_ik(robot, T, q0=q0)
    except ValueError as exc:
        raise invalid(["pose"], str(exc)) from None
    ik = {
        "status": r.status.value,
        "message": r.message,
        "method": r.method,
        "position_error": finite_or_none(r.position_error),
        "rotation_error": finite_or_none(r.rotation_error),
    }
    if r.success:
        return JSONResponse({
            "success": True, "q": r.q.tolist(), "cylinders": _states(robot, cyl, r.q),
            "ik": ik, "message": f"pose reached: {r.message}",
        })
    message = f"no cylinder lengths: {r.message}"
    if r.status is IKStatus.OUT_OF_LIMITS and len(r.solutions):
        story = _limit_story(diagnose_limits(robot, r.solutions[0], cyl))
        if story:
            message += f"; the nearest solution: {story}"
    return JSONResponse({
        "success": False, "q": None, "cylinders": None, "ik": ik, "message": message,
    })
