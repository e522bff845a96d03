"""Validation of the numbers, vectors, arrays and poses of a shape's JSON spec.

Every reader raises ``FieldError(loc, message)`` with ``loc`` the field's path in the request
(``("objects", 2, "radius")``), so the API answers 422 naming the field at fault. Lengths in
mm, within ``MAX_LENGTH_MM``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.model import MAX_LENGTH_MM
from kinematics.transforms import rigidity_error

__all__ = ["POSE_TOLERANCE", "number", "vector", "array", "parse_pose"]

#: Largest deviation from a rigid transform accepted in a pose (``rigidity_error``).
POSE_TOLERANCE = 1e-6


def number(value: Any, loc: tuple, what: str, positive: bool = True) -> float:
    """A finite number within ``MAX_LENGTH_MM`` (and > 0 with ``positive``)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FieldError(loc, f"{what} must be a number")
    x = float(value)
    if not math.isfinite(x):
        raise FieldError(loc, f"{what} must be finite")
    if positive and x <= 0:
        raise FieldError(loc, f"{what} must be positive, got {x:g}")
    if abs(x) > MAX_LENGTH_MM:
        raise FieldError(loc, f"{what} must be within {MAX_LENGTH_MM:g} mm")
    return x


def vector(value: Any, loc: tuple, what: str, positive: bool = False
           ) -> tuple[float, float, float]:
    """Three ``number``s ``[x, y, z]``; errors at ``loc + (k,)`` for entry ``k``."""
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise FieldError(loc, f"{what} must be a list of 3 numbers")
    return tuple(number(v, loc + (k,), what, positive) for k, v in enumerate(value))


def array(value: Any, loc: tuple, what: str, cols: int, dtype: type, cap: int) -> np.ndarray:
    """A read-only ``(n, cols)`` array from nested lists (or an array), at most ``cap`` rows:
    float coordinates within ``MAX_LENGTH_MM``, or whole indices (``dtype`` int)."""
    if isinstance(value, np.ndarray):
        A = value
    else:
        if not isinstance(value, list | tuple):
            raise FieldError(loc, f"{what} must be a list of [{', '.join('xyz'[:cols])}] rows"
                             if dtype is float else f"{what} must be a list of index triples")
        if len(value) > cap:
            raise FieldError(loc, f"{what} has {len(value)} rows, more than the cap of {cap}")
        try:
            A = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise FieldError(loc, f"{what} must hold only numbers") from None
    if A.ndim != 2 or A.shape[1] != cols or len(A) == 0:
        raise FieldError(loc, f"{what} must be a non-empty list of rows of {cols} numbers")
    if len(A) > cap:
        raise FieldError(loc, f"{what} has {len(A)} rows, more than the cap of {cap}")
    if not np.all(np.isfinite(A)):
        raise FieldError(loc, f"{what} must be finite")
    if dtype is float:
        if np.abs(A).max() > MAX_LENGTH_MM:
            raise FieldError(loc, f"{what} must be within {MAX_LENGTH_MM:g} mm")
        A = np.array(A, dtype=float)
    else:
        if np.any(A != np.round(A)):
            raise FieldError(loc, f"{what} must hold whole vertex indices")
        A = np.array(A, dtype=np.int64)
    A.setflags(write=False)
    return A


def parse_pose(value: Any, loc: tuple) -> np.ndarray:
    """A rigid 4x4 pose from nested lists (identity for None), read-only; ``FieldError`` at
    ``loc`` otherwise."""
    if value is None:
        T = np.eye(4)
    else:
        try:
            T = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise FieldError(loc, "pose must be a 4x4 list of numbers") from None
        if T.shape != (4, 4):
            raise FieldError(loc, f"pose must be 4x4, got shape {list(T.shape)}")
        if not np.all(np.isfinite(T)):
            raise FieldError(loc, "pose must be finite")
        if np.abs(T[:3, 3]).max() > MAX_LENGTH_MM:
            raise FieldError(loc, f"pose translation must be within {MAX_LENGTH_MM:g} mm")
        err = float(rigidity_error(T))
        if err > POSE_TOLERANCE:
            raise FieldError(loc, f"pose is not a rigid transform (rotation not orthonormal "
                             f"or last row not [0, 0, 0, 1]: deviation {err:.2g})")
    T.setflags(write=False)
    return T
