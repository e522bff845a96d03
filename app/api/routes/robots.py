"""Robot models: list and read."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from kinematics.ik import available_methods

from ..deps import RegistryDep, RobotDep
from ..schemas import JointSummary, RobotSummary

router = APIRouter(prefix="/robots", tags=["robots"])


@router.get("", response_model=list[RobotSummary])
def list_robots(registry: RegistryDep) -> list[RobotSummary]:
    """Every robot the service knows, built-in and custom."""
    return [
        RobotSummary(
            id=m.id, name=m.name, dof=m.dof, builtin=registry.is_builtin(m.id),
            convention=m.convention,
            joints=[
                JointSummary(name=j.name, type=j.type, lower=j.lower, upper=j.upper)
                for j in m.joints
            ],
            ik_methods=available_methods(m),
        )
        for m in registry.all()
    ]


@router.get("/{robot_id}")
def get_robot_model(robot: RobotDep) -> dict[str, Any]:
    """The robot's model JSON (the schema POST /robots takes)."""
    return robot.to_dict()
