"""Sphere: ``radius``, centred on the object's origin (solid; the pose's rotation is
irrelevant)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..distance import sphere_distance
from ..fields import number
from ..registry import KERNEL_CODES, ShapeKind, register_pair, register_shape
from ..segments import segment_point_distance
from ._common import fcl_object, no_rotation_par, translation


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    return {"radius": number(data["radius"], loc + ("radius",), "radius")}


def to_dict(o) -> dict[str, Any]:
    return {"radius": o.radius}


def bounds(o) -> tuple[np.ndarray, np.ndarray]:
    T = o.pose
    return T[:3, 3] - o.radius, T[:3, 3] + o.radius


def pack(objs: list) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(n, 3)`` and radii ``(n,)``: ``sphere_distance``'s arrays."""
    return (np.array([o.pose[:3, 3] for o in objs]).reshape(-1, 3),
            np.array([o.radius for o in objs], dtype=float))


def kernel_params(o) -> tuple[np.ndarray, np.ndarray]:
    return translation(o.pose[:3, 3]), no_rotation_par(o.radius)


def exact(o) -> tuple:
    import fcl

    return fcl_object(fcl.Sphere(o.radius), np.asarray(o.pose, dtype=float))


def path_cover(o) -> list[dict[str, Any]]:
    """Itself."""
    return [{"type": "sphere", "center": o.pose[:3, 3].tolist(), "radius": o.radius}]


KIND = register_shape(ShapeKind(
    name="sphere", required=("radius",), optional=(), parse=parse, to_dict=to_dict,
    bounds=bounds, pack=pack, code=KERNEL_CODES["sphere"], kernel_params=kernel_params,
    exact=exact, path_cover=path_cover))
register_pair("point", "sphere", sphere_distance, kernel="sphere_point")
# Segments to the centre (minus the radius): point paths.
register_pair("segment", "sphere", segment_point_distance)
