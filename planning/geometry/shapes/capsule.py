"""Capsule: the points within ``radius`` of the segment ``a``-``b`` (object frame; solid)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..distance import capsule_distance, segment_frame
from ..fields import number, vector
from ..registry import KERNEL_CODES, ShapeKind, register_pair, register_shape
from ..segments import segment_segment_distance
from ._common import fcl_object, no_rotation_par


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    radius = number(data["radius"], loc + ("radius",), "radius")
    return {"a": vector(data["a"], loc + ("a",), "a"),
            "b": vector(data["b"], loc + ("b",), "b"), "radius": radius}


def to_dict(o) -> dict[str, Any]:
    return {"a": list(o.a), "b": list(o.b), "radius": o.radius}


def world_ends(o) -> tuple[np.ndarray, np.ndarray]:
    """The segment's ends ``a``, ``b`` ``(3,)`` in the world."""
    T = o.pose
    return T[:3, :3] @ o.a + T[:3, 3], T[:3, :3] @ o.b + T[:3, 3]


def bounds(o) -> tuple[np.ndarray, np.ndarray]:
    a, b = world_ends(o)
    return np.minimum(a, b) - o.radius, np.maximum(a, b) + o.radius


def pack(objs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World ends ``A, B (n, 3)`` and radii ``(n,)``: ``capsule_distance``'s arrays."""
    return (np.array([o.pose[:3, :3] @ o.a + o.pose[:3, 3] for o in objs]).reshape(-1, 3),
            np.array([o.pose[:3, :3] @ o.b + o.pose[:3, 3] for o in objs]).reshape(-1, 3),
            np.array([o.radius for o in objs], dtype=float))


def kernel_params(o) -> tuple[np.ndarray, np.ndarray]:
    """A frame at the segment's middle with z along it; radius and half length."""
    A, B = world_ends(o)
    from ..distance import frames_along

    T = frames_along(0.5 * (A + B), B - A)
    return T, no_rotation_par(o.radius, 0.5 * float(np.linalg.norm(B - A)))


def exact(o) -> tuple:
    import fcl

    a, b = world_ends(o)
    L = float(np.linalg.norm(b - a))
    geom = fcl.Capsule(o.radius, L) if L > 0 else fcl.Sphere(o.radius)
    return fcl_object(geom, segment_frame(a, b))


def path_cover(o) -> list[dict[str, Any]]:
    """Itself, in the world."""
    R, p = o.pose[:3, :3], o.pose[:3, 3]
    a = R @ np.asarray(o.a) + p
    b = R @ np.asarray(o.b) + p
    return [{"type": "capsule", "a": a.tolist(), "b": b.tolist(), "radius": o.radius}]


KIND = register_shape(ShapeKind(
    name="capsule", required=("a", "b", "radius"), optional=(), parse=parse,
    to_dict=to_dict, bounds=bounds, pack=pack, code=KERNEL_CODES["capsule"],
    kernel_params=kernel_params, exact=exact, path_cover=path_cover))
register_pair("point", "capsule", capsule_distance, kernel="capsule_point")
# Segments to the axis (minus the radius): point paths and drilling envelopes.
register_pair("segment", "capsule", segment_segment_distance)
