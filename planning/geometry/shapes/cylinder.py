"""Cylinder: ``radius``, ``height``, axis along local z, centred on the object's origin
(solid)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..distance import cylinder_distance
from ..fields import number
from ..registry import KERNEL_CODES, ShapeKind, register_pair, register_shape
from ._common import fcl_object, no_rotation_par


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    radius = number(data["radius"], loc + ("radius",), "radius")
    return {"radius": radius, "height": number(data["height"], loc + ("height",), "height")}


def to_dict(o) -> dict[str, Any]:
    return {"radius": o.radius, "height": o.height}


def bounds(o) -> tuple[np.ndarray, np.ndarray]:
    T = o.pose
    z = T[:3, 2]
    half = 0.5 * o.height * np.abs(z) + o.radius * np.sqrt(np.maximum(1 - z * z, 0.0))
    return T[:3, 3] - half, T[:3, 3] + half


def pack(objs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poses ``(n, 4, 4)``, radii ``(n,)``, heights ``(n,)``: ``cylinder_distance``'s."""
    return (np.array([o.pose for o in objs]).reshape(-1, 4, 4),
            np.array([o.radius for o in objs], dtype=float),
            np.array([o.height for o in objs], dtype=float))


def kernel_params(o) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(o.pose, dtype=float), no_rotation_par(o.radius, 0.5 * o.height)


def exact(o) -> tuple:
    import fcl

    return fcl_object(fcl.Cylinder(o.radius, o.height), np.asarray(o.pose, dtype=float))


def path_cover(o) -> list[dict[str, Any]]:
    """The capsule along its axis."""
    R, p = o.pose[:3, :3], o.pose[:3, 3]
    axis = R[:, 2] * (0.5 * o.height)
    return [{"type": "capsule", "a": (p - axis).tolist(), "b": (p + axis).tolist(),
             "radius": o.radius}]


KIND = register_shape(ShapeKind(
    name="cylinder", required=("radius", "height"), optional=(), parse=parse,
    to_dict=to_dict, bounds=bounds, pack=pack, code=KERNEL_CODES["cylinder"],
    kernel_params=kernel_params, exact=exact, path_cover=path_cover))
register_pair("point", "cylinder", cylinder_distance, kernel="cylinder_point")
