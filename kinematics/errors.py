"""The small exception hierarchy of the kinematics and planning packages."""

from __future__ import annotations

import re
from collections.abc import Iterable

__all__ = ["KinematicsError", "MethodUnavailableError", "FieldError", "Loc", "loc_from_path"]

#: Where an input is at fault: field names and list indices, e.g. ``("holes", 3)``.
Loc = tuple[str | int, ...]


def _rebuild(cls: type, args: tuple, state: dict) -> ValueError:
    error = cls.__new__(cls)
    ValueError.__init__(error, *args)
    error.__dict__.update(state)
    return error


class KinematicsError(ValueError):
    """Invalid input to a kinematics function.

    Subclasses take their own constructor arguments; every one pickles intact (its message,
    arguments and attributes), so an error raised in a worker process reaches the caller."""

    def __reduce__(self):
        return _rebuild, (type(self), self.args, self.__dict__)


class MethodUnavailableError(KinematicsError):
    """A valid method that this robot cannot use now (e.g. no closed form, nothing trained)."""

    def __init__(self, method: str, message: str):
        super().__init__(message)
        self.method = method


class FieldError(ValueError):
    """An input that a domain check found wrong: ``loc`` names the field (names and list
    indices, relative to the request body or job params, e.g. ``("durations",)`` or
    ``("params", "iterations")``; one name alone is a one-part ``loc``), ``message`` says
    why in words (``str(error)`` too).

    Kinematics and planning functions name their arguments as the service's requests do,
    so the service answers 422 at ``["body", *loc]`` without reading the message. It
    pickles intact, ``loc`` included, so one raised in a worker process arrives whole."""

    def __init__(self, loc: str | Iterable[str | int], message: str):
        super().__init__(message)
        self.loc: Loc = (loc,) if isinstance(loc, str) else tuple(loc)
        self.message = message

    def __reduce__(self):
        return _rebuild, (type(self), self.args, self.__dict__)


_PATH_PART = re.compile(r"\[(\d+)\]|([^.\[\]]+)")


def loc_from_path(path: str) -> Loc:
    """A dotted field path as a ``loc``: ``"joints[2].lower"`` -> ``("joints", 2, "lower")``."""
    return tuple(int(index) if index else name for index, name in _PATH_PART.findall(path))
