"""Box: ``size`` [x, y, z] full side lengths, centred on the object's origin (solid)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..distance import box_distance
from ..fields import vector
from ..registry import KERNEL_CODES, ShapeKind, register_pair, register_shape
from ..segments import segment_box_distance
from ._common import fcl_object


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    return {"size": vector(data["size"], loc + ("size",), "size", True)}


def to_dict(o) -> dict[str, Any]:
    return {"size": list(o.size)}


def bounds(o) -> tuple[np.ndarray, np.ndarray]:
    T = o.pose
    half = np.abs(T[:3, :3]) @ (0.5 * np.asarray(o.size))
    return T[:3, 3] - half, T[:3, 3] + half


def pack(objs: list) -> tuple[np.ndarray, np.ndarray]:
    """Poses ``(n, 4, 4)`` and sizes ``(n, 3)``: ``box_distance``'s arrays."""
    return (np.array([o.pose for o in objs]).reshape(-1, 4, 4),
            np.array([o.size for o in objs], dtype=float).reshape(-1, 3))


def kernel_params(o) -> tuple[np.ndarray, np.ndarray]:
    par = np.zeros(4)
    par[:3] = 0.5 * np.array(o.size, dtype=float)
    return np.asarray(o.pose, dtype=float), par


def exact(o) -> tuple:
    import fcl

    return fcl_object(fcl.Box(*o.size), np.asarray(o.pose, dtype=float))


def path_cover(o) -> list[dict[str, Any]]:
    """Its axis-aligned bounding box."""
    R, p = o.pose[:3, :3], o.pose[:3, 3]
    half = 0.5 * np.abs(R) @ np.asarray(o.size)
    return [{"type": "box", "lower": (p - half).tolist(), "upper": (p + half).tolist()}]


KIND = register_shape(ShapeKind(
    name="box", required=("size",), optional=(), parse=parse, to_dict=to_dict,
    bounds=bounds, pack=pack, code=KERNEL_CODES["box"], kernel_params=kernel_params,
    exact=exact, path_cover=path_cover))
register_pair("point", "box", box_distance, kernel="box_point")
# Segments to an axis-aligned box (signed): point paths.
register_pair("segment", "box", segment_box_distance)
