"""Request and response bodies of the cylinder endpoints (units: mm, rad, s)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, StringConstraints

from ..fields import MAX_COORDINATE_MM, JointVector, pose_type
from .schemas import Body, body_examples

#: A cylinder length in a request, mm.
Length = Annotated[float, Field(gt=0, le=MAX_COORDINATE_MM)]
CylinderName = Annotated[str, StringConstraints(min_length=1, max_length=200)]

__all__ = [
    "CylindersRequest",
    "CylinderState",
    "CylindersResponse",
    "CylindersInverseRequest",
    "CylindersInverseResponse",
    "PoseToCylindersRequest",
    "IKSummary",
    "PoseToCylindersResponse",
]


class CylindersRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"q": [0.3, 0.5, -0.5, -0.5, 0.1, 0.0], "qd": [0.0, 0.1, 0.1, 0.0, 0.0, 0.0]},
        robot="pile_driver"))

    q: JointVector = Field(description="One configuration (dof values), rad or mm per joint")
    qd: JointVector | None = Field(
        None, description="Joint speeds (dof values, rad/s or mm/s); adds each cylinder's speed"
    )


class CylinderState(BaseModel):
    name: str
    joint: str = Field(description="Name of the joint the cylinder drives")
    length: float = Field(description="Pin-to-pin length, mm")
    stroke: float = Field(description="length - min_length, mm")
    min_length: float = Field(description="Retracted length, mm")
    max_length: float = Field(description="Extended length, mm")
    within_limits: bool = Field(description="min_length <= length <= max_length")
    speed: float | None = Field(
        None, description="mm/s, positive = extending; only when joint speeds were given"
    )


class CylindersResponse(BaseModel):
    cylinders: list[CylinderState]
    joints_within_limits: bool


class CylindersInverseRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"lengths": {"boom": 490.0, "stick": 500.0}, "q": [0.3, 0.0, 0.0, -0.5, 0.1, 0.0]},
        robot="pile_driver"))

    lengths: dict[CylinderName, Length] = Field(
        min_length=1, max_length=64, description="Cylinder lengths (mm) by cylinder name"
    )
    q: JointVector | None = Field(
        None, description="Values (dof) for the joints without a given cylinder; default 0"
    )


class CylindersInverseResponse(BaseModel):
    q: list[float]
    joints_within_limits: bool
    cylinders: list[CylinderState] = Field(description="Every cylinder at the answer q")


class PoseToCylindersRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"pose": [[0.8047, -0.458, -0.3777, 1732.3], [0.3534, -0.1417, 0.9247, 535.9],
                  [-0.477, -0.8776, 0.0479, 327.5], [0, 0, 0, 1]]}, robot="pile_driver"))

    pose: pose_type(4) = Field(description="Target tool pose, 4x4, world frame (that of fk), mm")
    q0: JointVector | None = Field(
        None, description="Initial guess / preferred configuration (dof values)"
    )


class IKSummary(BaseModel):
    status: Literal["ok", "unreachable", "out_of_limits", "not_converged"]
    message: str
    method: str
    position_error: float | None = Field(description="mm; null when nothing was computed")
    rotation_error: float | None = Field(description="rad; null when nothing was computed")


class PoseToCylindersResponse(BaseModel):
    success: bool
    q: list[float] | None = Field(description="Joint solution; null when the pose is not reached")
    cylinders: list[CylinderState] | None
    ik: IKSummary
    message: str
