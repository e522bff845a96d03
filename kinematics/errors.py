"""The small exception hierarchy of the kinematics package."""

from __future__ import annotations

__all__ = ["KinematicsError", "MethodUnavailableError"]


class KinematicsError(ValueError):
    """Invalid input to a kinematics function.

    Subclasses take their own constructor arguments; every one pickles intact (its message,
    arguments and attributes), so an error raised in a worker process reaches the caller."""

    def __reduce__(self):
        return _rebuild, (type(self), self.args, self.__dict__)


def _rebuild(cls: type, args: tuple, state: dict) -> KinematicsError:
    error = cls.__new__(cls)
    ValueError.__init__(error, *args)
    error.__dict__.update(state)
    return error


class MethodUnavailableError(KinematicsError):
    """A valid method that this robot cannot use now (e.g. no closed form, nothing trained)."""

    def __init__(self, method: str, message: str):
        super().__init__(message)
        self.method = method
