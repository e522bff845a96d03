"""Helpers the shape modules share: FCL objects, a translation, a kernel parameter row."""

from __future__ import annotations

from typing import Any

import numpy as np


def fcl_object(geom: Any, T: np.ndarray) -> tuple:
    """The exact stage's item of an FCL geometry posed ``T (4, 4)`` in the world."""
    import fcl

    tf = fcl.Transform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
    return ("fcl", fcl.CollisionObject(geom, tf))


def translation(p: np.ndarray) -> np.ndarray:
    """The pose ``(4, 4)`` that moves the origin to ``p (3,)``."""
    T = np.eye(4)
    T[:3, 3] = p
    return T


def no_rotation_par(*values: float) -> np.ndarray:
    """A kernel parameter row ``(4,)``: ``values`` then zeros."""
    par = np.zeros(4)
    par[:len(values)] = values
    return par
