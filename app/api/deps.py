"""Dependencies shared by the routes, as ``Annotated`` aliases."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path, Request

from kinematics.model import RobotModel

from ..config import Settings
from ..registry import RobotRegistry
from .errors import not_found

__all__ = ["SettingsDep", "RegistryDep", "RobotDep"]


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_registry(request: Request) -> RobotRegistry:
    return request.app.state.registry


SettingsDep = Annotated[Settings, Depends(get_settings)]
RegistryDep = Annotated[RobotRegistry, Depends(get_registry)]


def get_robot(
    registry: RegistryDep,
    robot_id: Annotated[str, Path(description="Robot id, e.g. 'glt_palletizer'")],
) -> RobotModel:
    try:
        return registry.get(robot_id)
    except KeyError:
        raise not_found("robot", robot_id) from None


RobotDep = Annotated[RobotModel, Depends(get_robot)]
