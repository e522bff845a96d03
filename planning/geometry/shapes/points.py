"""Point cloud: ``points`` [[x, y, z], ...] (object frame), each inflated by ``radius``;
``resolution`` (default ``radius``) is the voxel size the sphere stage clusters them at
(one ball per voxel, ``cover_points``); the exact stage uses every point. Also the ball set
of the pair table: the ``("point", "balls")`` row serves meshes and point clouds."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..distance import ball_set_distance
from ..fields import array, number
from ..registry import KERNEL_CODES, Budget, ShapeKind, register_pair, register_shape

__all__ = ["MAX_POINTS"]

#: Most points of all ``points`` objects of one scene together.
MAX_POINTS = 200_000
#: Most boxes covering one point cloud among a point path's obstacles.
MAX_CLOUD_BOXES = 400


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    radius = number(data["radius"], loc + ("radius",), "radius")
    pts = array(data["points"], loc + ("points",), "points", 3, float, MAX_POINTS)
    res = data.get("resolution")
    res = radius if res is None else number(res, loc + ("resolution",), "resolution")
    return {"points": pts, "radius": radius, "resolution": res}


def to_dict(o) -> dict[str, Any]:
    return {"points": o.points.tolist(), "radius": o.radius, "resolution": o.resolution}


def balls(o, resolution: float) -> np.ndarray:
    """Balls covering the inflated points, one per voxel of the cloud's own
    ``resolution`` (the scene's mesh resolution does not apply)."""
    from ..spheres import cover_points

    return cover_points(o.world_points(), o.radius, o.resolution)


def exact(o) -> tuple:
    """The points themselves (a k-d tree over them) and their radius."""
    from scipy.spatial import cKDTree

    P = o.world_points()
    return ("points", P, cKDTree(P), float(o.radius))


def path_cover(o) -> list[dict[str, Any]]:
    """Axis-aligned boxes covering the inflated points: one per occupied cell of a grid
    coarse enough for at most ``MAX_CLOUD_BOXES`` cells."""
    P, radius = o.world_points(), float(o.radius)
    lo, hi = P.min(axis=0), P.max(axis=0)
    cell = max(float(np.max(hi - lo)) / 4.0, radius, 1.0)
    while True:
        keys = np.floor((P - lo) / cell).astype(np.int64)
        cells, inverse = np.unique(keys, axis=0, return_inverse=True)
        if len(cells) <= MAX_CLOUD_BOXES:
            break
        cell *= 1.5
    inverse = inverse.reshape(-1)
    boxes = []
    for k in range(len(cells)):
        Q = P[inverse == k]
        a, b = Q.min(axis=0) - radius, Q.max(axis=0) + radius
        boxes.append({"type": "box", "lower": a.tolist(), "upper": b.tolist()})
    return boxes


KIND = register_shape(ShapeKind(
    name="points", required=("points", "radius"), optional=("resolution",), parse=parse,
    to_dict=to_dict, balls=balls, code=KERNEL_CODES["balls"], exact=exact,
    path_cover=path_cover,
    budget=Budget("points", lambda o: len(o.points), MAX_POINTS, "points",
                  f"the scene's point clouds hold more than {MAX_POINTS} points together")))
register_pair("point", "balls", ball_set_distance, kernel="ballset_distance")
