"""Dependencies shared by the routes, as ``Annotated`` aliases."""

from __future__ import annotations

import hmac
from typing import Annotated

from fastapi import Depends, Path, Request

from kinematics.model import RobotModel

from ..config import Settings
from ..registry import RobotRegistry
from ..scenes import SceneRegistry
from .errors import http_error, not_found

__all__ = ["SettingsDep", "RegistryDep", "RobotDep", "ScenesDep", "get_scenes",
           "require_api_key"]


def get_settings(request: Request) -> Settings:
    return request.app.state.settings


def get_registry(request: Request) -> RobotRegistry:
    return request.app.state.registry


def get_scenes(request: Request) -> SceneRegistry:
    return request.app.state.scenes


SettingsDep = Annotated[Settings, Depends(get_settings)]
RegistryDep = Annotated[RobotRegistry, Depends(get_registry)]
ScenesDep = Annotated[SceneRegistry, Depends(get_scenes)]


def get_robot(
    registry: RegistryDep,
    robot_id: Annotated[str, Path(description="Robot id, e.g. 'glt_palletizer'")],
) -> RobotModel:
    try:
        return registry.get(robot_id)
    except KeyError:
        raise not_found("robot", robot_id) from None


RobotDep = Annotated[RobotModel, Depends(get_robot)]


def require_api_key(request: Request) -> None:
    """With ``KINOPLAN_API_KEY`` set, state-changing requests need ``Authorization: Bearer
    <key>`` (401 otherwise). Without a key the service is open (it binds to 127.0.0.1)."""
    key = request.app.state.settings.api_key
    if not key:
        return
    header = request.headers.get("authorization", "")
    scheme, _, token = header.partition(" ")
    if scheme.lower() != "bearer" or not hmac.compare_digest(token.strip().encode(),
                                                             key.encode()):
        raise http_error(401, ["header", "authorization"],
                         "this request changes state: send 'Authorization: Bearer <api key>'",
                         "unauthorized")
