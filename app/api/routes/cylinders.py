"""Hydraulic cylinders of one robot: joint angles <-> cylinder lengths, pose -> lengths.

A robot without cylinder data answers 409: the request is valid, the robot (as stored now)
cannot serve it, as for an IK method it has not been trained for.
"""

from __future__ import annotations

import math

import numpy as np
from fastapi import APIRouter, HTTPException
from fastapi.responses import JSONResponse

from kinematics.cylinders import CylinderError, CylinderSet, cylinder_set
from kinematics.ik import IKStatus, solve_ik
from kinematics.model import RobotModel

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
from .kinematics import joint_rows

router = APIRouter(prefix="/robots/{robot_id}", tags=["cylinders"])


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


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _limit_story(robot: RobotModel, cyl: CylinderSet, q: np.ndarray) -> str:
    """What the nearest out-of-limits solution ``q (dof,)`` asks of each joint it violates
    and of the cylinders driving those joints."""
    lengths = cyl.lengths(q)
    parts = []
    for i, j in enumerate(robot.joints):
        if j.lower - 1e-9 <= q[i] <= j.upper + 1e-9:
            continue
        part = (
            f"joint '{j.name}' needs {math.degrees(q[i]):.1f} deg (limits "
            f"{math.degrees(j.lower):.1f} .. {math.degrees(j.upper):.1f} deg)"
        )
        for name in (n for n in cyl.names if cyl.joint_of(n) == i):
            L = float(lengths[name])
            lo, hi = cyl.limits(name)
            if not math.isfinite(L):
                part += f", which cylinder '{name}''s linkage cannot take"
            elif L < lo:
                part += f", cylinder '{name}' would be {L:.1f} mm, below its retracted {lo:.1f} mm"
            elif L > hi:
                part += f", cylinder '{name}' would be {L:.1f} mm, beyond its extended {hi:.1f} mm"
            elif abs(cyl.joints_from_lengths({name: L})[i] - q[i]) < 1e-6:
                part += f", within the stroke of cylinder '{name}' but past the joint stop"
            else:
                part += f", past the dead point of cylinder '{name}' (no length of it gives this)"
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
        "position_error": _finite_or_none(r.position_error),
        "rotation_error": _finite_or_none(r.rotation_error),
    }
    if r.success:
        return JSONResponse({
            "success": True, "q": r.q.tolist(), "cylinders": _states(robot, cyl, r.q),
            "ik": ik, "message": f"pose reached: {r.message}",
        })
    message = f"no cylinder lengths: {r.message}"
    if r.status is IKStatus.OUT_OF_LIMITS and len(r.solutions):
        story = _limit_story(robot, cyl, r.solutions[0])
        if story:
            message += f"; the nearest solution: {story}"
    return JSONResponse({
        "success": False, "q": None, "cylinders": None, "ik": ik, "message": message,
    })
