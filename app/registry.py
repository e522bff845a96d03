"""Where the service finds robot models by id."""

from __future__ import annotations

from kinematics.library import builtin_models
from kinematics.model import RobotModel

__all__ = ["RobotRegistry"]


class RobotRegistry:
    """The robots the service knows: the built-ins (read-only)."""

    def __init__(self) -> None:
        self._builtin = builtin_models()

    def ids(self) -> list[str]:
        return list(self._builtin)

    def get(self, robot_id: str) -> RobotModel:
        """The model ``robot_id``; ``KeyError`` if unknown."""
        return self._builtin[robot_id]

    def is_builtin(self, robot_id: str) -> bool:
        return robot_id in self._builtin

    def all(self) -> list[RobotModel]:
        return list(self._builtin.values())
