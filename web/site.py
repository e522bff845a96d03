"""A stored scene (a site's geometry, ``app.scenes``) drawn in the viewer.

The objects come validated (``planning.collision.shapes.SceneObject``: pose ``T_world_object``,
lengths mm). Each object is one node under the scene's root, named after its id (``/``
replaced by ``_``, made unique)::

    /scene/<scene id>                the scene's root frame
    /scene/<scene id>/<object id>    box, sphere, cylinder (axis local z, centred), capsule
                                     (a mesh between its end balls), mesh (``scale``
                                     applied), or point cloud (coloured by height)

``draw_site`` returns the nodes and the world bounds of what it drew (for the camera).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .meshes import bounds_of, box_corners, node_safe
from .scene import MM_TO_M, height_colors, segment_pose, wxyz_from_matrix

__all__ = ["SCENE_ROOT", "OBJECT_COLOR", "SiteNodes", "draw_site", "object_bounds_mm"]

SCENE_ROOT = "/scene"
OBJECT_COLOR = (120, 140, 170)
#: Smallest drawn size (m) of a cloud's points, so a thin radius still shows.
MIN_POINT_SIZE_M = 0.004


@dataclass
class SiteNodes:
    """The nodes of one drawn scene: ``handles`` by node name (root first), the node of
    each object by its id, and the world ``bounds`` (mm) of the objects (None if empty)."""

    scene_id: str
    root: str
    handles: dict[str, Any] = field(default_factory=dict)
    objects: dict[str, str] = field(default_factory=dict)
    bounds: tuple[np.ndarray, np.ndarray] | None = None

    @property
    def names(self) -> list[str]:
        """The object nodes (without the root)."""
        return list(self.objects.values())

    def remove(self) -> None:
        root = self.handles.get(self.root)
        if root is not None:
            root.remove()
        self.handles.clear()


def _capsule_mesh(length_m: float, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """A capsule centred on the origin, axis z, ``length_m`` between its end balls' centres."""
    import trimesh

    c = trimesh.creation.capsule(height=max(length_m, 0.0), radius=radius_m, count=[24, 24])
    return np.asarray(c.vertices, dtype=np.float32), np.asarray(c.faces, dtype=np.uint32)


def object_bounds_mm(o: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """World bounds ``(lower, upper)`` mm of a ``SceneObject``."""
    T = np.asarray(o.pose, dtype=float)
    if o.type == "box":
        h = 0.5 * np.asarray(o.size, dtype=float)
        return bounds_of(box_corners(-h, h) @ T[:3, :3].T + T[:3, 3])
    if o.type == "sphere":
        return T[:3, 3] - o.radius, T[:3, 3] + o.radius
    if o.type == "cylinder":
        h = np.array([o.radius, o.radius, 0.5 * o.height])
        return bounds_of(box_corners(-h, h) @ T[:3, :3].T + T[:3, 3])
    if o.type == "capsule":
        ends = np.array([o.a, o.b], dtype=float) @ T[:3, :3].T + T[:3, 3]
        return ends.min(axis=0) - o.radius, ends.max(axis=0) + o.radius
    if o.type == "mesh":
        return bounds_of(o.world_vertices())
    lo_hi = bounds_of(o.world_points())
    if lo_hi is None:
        return None
    return lo_hi[0] - o.radius, lo_hi[1] + o.radius


def _add_object(scene: Any, name: str, o: Any, color: tuple[int, int, int]) -> Any:
    T = np.asarray(o.pose, dtype=float)
    pose = {"position": T[:3, 3] * MM_TO_M, "wxyz": wxyz_from_matrix(T[:3, :3])}
    if o.type == "box":
        return scene.add_box(name, color=color, dimensions=np.asarray(o.size) * MM_TO_M,
                             **pose)
    if o.type == "sphere":
        return scene.add_icosphere(name, radius=o.radius * MM_TO_M, color=color,
                                   subdivisions=3, **pose)
    if o.type == "cylinder":
        return scene.add_cylinder(name, radius=o.radius * MM_TO_M, height=o.height * MM_TO_M,
                                  color=color, radial_segments=32, **pose)
    if o.type == "capsule":
        a = T[:3, :3] @ np.asarray(o.a, dtype=float) + T[:3, 3]
        b = T[:3, :3] @ np.asarray(o.b, dtype=float) + T[:3, 3]
        mid, wxyz, length = segment_pose(a * MM_TO_M, b * MM_TO_M)
        V, F = _capsule_mesh(length, o.radius * MM_TO_M)
        return scene.add_mesh_simple(name, V, F, color=color, position=mid, wxyz=wxyz)
    if o.type == "mesh":
        V = np.asarray(o.vertices, dtype=float) * np.asarray(o.scale, dtype=float)
        return scene.add_mesh_simple(name, (V * MM_TO_M).astype(np.float32),
                                     np.asarray(o.faces, dtype=np.uint32), color=color,
                                     side="double", flat_shading=True, **pose)
    # points: in the object frame, coloured by their world height
    P = np.asarray(o.points, dtype=float)
    colors = height_colors(o.world_points()[:, 2])
    return scene.add_point_cloud(name, (P * MM_TO_M).astype(np.float32), colors,
                                 point_size=max(2.0 * o.radius * MM_TO_M, MIN_POINT_SIZE_M),
                                 point_shape="circle", precision="float32", **pose)


def draw_site(scene: Any, scene_id: str, objects: Sequence[Any],
              color: tuple[int, int, int] = OBJECT_COLOR, *, root: str | None = None
              ) -> SiteNodes:
    """Draw ``objects`` (``SceneObject``s) under ``root`` (default ``/scene/<scene_id>``)."""
    root = f"{SCENE_ROOT}/{scene_id}" if root is None else root
    out = SiteNodes(scene_id, root)
    out.handles[root] = scene.add_frame(root, show_axes=False)
    taken: set[str] = set()
    lows, highs = [], []
    for o in objects:
        name = f"{root}/{node_safe(str(o.id), taken)}"
        out.handles[name] = _add_object(scene, name, o, color)
        out.objects[str(o.id)] = name
        b = object_bounds_mm(o)
        if b is not None:
            lows.append(b[0])
            highs.append(b[1])
    if lows:
        out.bounds = (np.min(lows, axis=0), np.max(highs, axis=0))
    return out
