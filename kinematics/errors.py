"""The small exception hierarchy of the kinematics package."""

from __future__ import annotations

__all__ = ["KinematicsError", "MethodUnavailableError"]


class KinematicsError(ValueError):
    """Invalid input to a kinematics function."""


class MethodUnavailableError(KinematicsError):
    """A valid method that this robot cannot use now (e.g. no closed form, nothing trained)."""

    def __init__(self, method: str, message: str):
        super().__init__(message)
        self.method = method
