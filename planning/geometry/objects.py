"""Scene objects: the API format of a site's geometry, validated through the shape registry.

An object is a dict ``{"type": ..., "id": optional name, "pose": 4x4 (default identity),
...}`` with lengths in mm and the pose ``T_world_object`` (row-major nested lists). The
built-in types (``planning.geometry.shapes``):

=========  =================================================================================
type       fields (object frame)
=========  =================================================================================
box        ``size`` [x, y, z]: full side lengths, centred on the origin
sphere     ``radius``, centred on the origin
cylinder   ``radius``, ``height``: axis local z, centred on the origin
capsule    ``a``, ``b`` [x, y, z]: the segment's end points; ``radius``
mesh       ``mesh``: the name of a stored mesh (vertices come from the service's store),
           or inline ``vertices`` [[x, y, z], ...] and ``faces`` [[i, j, k], ...];
           ``scale`` (one number or [sx, sy, sz], default 1) multiplies the vertices
points     ``points`` [[x, y, z], ...]: a scanned point cloud, each point inflated by
           ``radius``; ``resolution`` (default ``radius``) is the voxel size it is
           clustered at for the sphere stage (the exact stage uses every point)
=========  =================================================================================

Other types are registered by their modules (``planning.geometry.registry``). Invalid input
raises ``FieldError(("objects", i, field), message)``. Caps (``MAX_OBJECTS`` and the shapes'
scene budgets: ``MAX_POINTS``, ``MAX_SCENE_TRIANGLES``) bound the work one scene can ask for.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.model import MAX_NAME_LENGTH

from .fields import parse_pose
from .table import shape_kind, shape_names

__all__ = [
    "MAX_OBJECTS",
    "SceneObject",
    "MeshResolver",
    "object_types",
    "parse_object",
    "parse_objects",
    "check_caps",
]

#: Most objects in one scene.
MAX_OBJECTS = 1000

#: A stored mesh by name -> ``(vertices (V, 3) mm, faces (F, 3))``; raises ``KeyError`` for
#: an unknown name.
MeshResolver = Callable[[str], tuple[np.ndarray, np.ndarray]]

_COMMON = ("type", "id", "pose")


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One validated scene object (see the module docstring). Arrays are read-only;
    ``pose`` is ``T_world_object (4, 4)``. For ``mesh``: ``vertices (V, 3)`` as given
    (before ``scale``), ``faces (F, 3)``, ``mesh`` the stored mesh's name or None for an
    inline mesh. For ``points``: ``points (N, 3)`` in the object frame. A registered shape's
    own fields that are none of these are in ``extra`` and read as attributes too."""

    type: str
    id: str
    pose: np.ndarray
    size: tuple[float, float, float] | None = None
    radius: float | None = None
    height: float | None = None
    a: tuple[float, float, float] | None = None
    b: tuple[float, float, float] | None = None
    mesh: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    vertices: np.ndarray | None = field(default=None, repr=False)
    faces: np.ndarray | None = field(default=None, repr=False)
    points: np.ndarray | None = field(default=None, repr=False)
    resolution: float | None = None
    extra: Mapping[str, Any] = field(default_factory=dict, repr=False)

    def __getattr__(self, name: str) -> Any:
        # Only reached for names that are not fields: a registered shape's own ones.
        extra = self.__dict__.get("extra", {})
        if name in extra:
            return extra[name]
        raise AttributeError(f"a {self.__dict__.get('type', '?')} object has no {name!r}")

    @property
    def kind(self):
        """The object's ``ShapeKind`` (``planning.geometry.registry``)."""
        return shape_kind(self.type)

    def world_vertices(self) -> np.ndarray:
        """A mesh's vertices ``(V, 3)`` in the world frame, mm (``scale`` applied)."""
        V = self.vertices * np.asarray(self.scale)
        return V @ self.pose[:3, :3].T + self.pose[:3, 3]

    def world_points(self) -> np.ndarray:
        """A point cloud's points ``(N, 3)`` in the world frame, mm."""
        return self.points @ self.pose[:3, :3].T + self.pose[:3, 3]

    def world_point(self, local) -> np.ndarray:
        """A point ``(3,)`` of the object frame in the world frame, mm."""
        return self.pose[:3, :3] @ local + self.pose[:3, 3]

    def to_dict(self) -> dict[str, Any]:
        """The object in the API format (``parse_object`` reads it back to the same
        object). A stored mesh is written by name, an inline one with its arrays."""
        out: dict[str, Any] = {"type": self.type, "id": self.id, "pose": self.pose.tolist()}
        out.update(self.kind.to_dict(self))
        return out


_FIELD_NAMES = frozenset(f.name for f in fields(SceneObject))


def object_types() -> tuple[str, ...]:
    """The object types a scene accepts now (the registered shapes)."""
    return shape_names()


def parse_object(data: Any, index: int, resolve_mesh: MeshResolver | None = None,
                 prefix: tuple = ("objects",)) -> SceneObject:
    """Validate one object dict; errors at ``prefix + (index, field)``."""
    loc = prefix + (index,)
    if not isinstance(data, dict):
        raise FieldError(loc, "each object must be a JSON object with a 'type'")
    kind = data.get("type")
    types = object_types()
    if kind not in types:
        what = "is missing" if kind is None else f"'{kind}' is not a known type"
        raise FieldError(loc + ("type",), f"type {what}; known types: {', '.join(types)}")
    shape = shape_kind(kind)
    allowed = set(_COMMON) | set(shape.required) | set(shape.optional)
    for key in data:
        if key not in allowed:
            raise FieldError(loc + (str(key),), f"unknown field for a {kind}; a {kind} has "
                             f"{', '.join(sorted(allowed))}")
    for key in shape.required:
        if key not in data:
            raise FieldError(loc + (key,), f"a {kind} needs '{key}'")
    oid = data.get("id")
    if oid is None:
        oid = f"{kind}{index}"
    elif not isinstance(oid, str) or not oid or len(oid) > MAX_NAME_LENGTH \
            or not oid.isprintable():
        raise FieldError(loc + ("id",), f"id must be printable text of 1 to "
                         f"{MAX_NAME_LENGTH} characters")
    pose = parse_pose(data.get("pose"), loc + ("pose",))
    values = shape.parse(data, loc, resolve_mesh)
    own = {k: v for k, v in values.items() if k in _FIELD_NAMES}
    extra = {k: v for k, v in values.items() if k not in _FIELD_NAMES}
    return SceneObject(type=kind, id=oid, pose=pose, extra=extra, **own)


def parse_objects(items: Any, resolve_mesh: MeshResolver | None = None,
                  prefix: tuple = ("objects",)) -> tuple[SceneObject, ...]:
    """Validate a list of object dicts: each object, unique ids and the scene's caps."""
    if not isinstance(items, list | tuple):
        raise FieldError(prefix, "objects must be a list of objects")
    if len(items) > MAX_OBJECTS:
        raise FieldError(prefix, f"a scene holds at most {MAX_OBJECTS} objects, got "
                         f"{len(items)}")
    objects = tuple(parse_object(d, i, resolve_mesh, prefix) for i, d in enumerate(items))
    check_caps(objects, prefix)
    return objects


def check_caps(objects: Iterable[SceneObject], prefix: tuple = ("objects",)) -> None:
    """Unique ids, and each scene budget (``MAX_POINTS``, ``MAX_SCENE_TRIANGLES``: the
    shapes' ``budget``) over the scene."""
    seen: dict[str, int] = {}
    used: dict[str, int] = {}
    for i, obj in enumerate(objects):
        if obj.id in seen:
            raise FieldError(prefix + (i, "id"), f"id '{obj.id}' is already used by object "
                             f"{seen[obj.id]}")
        seen[obj.id] = i
        budget = obj.kind.budget
        if budget is not None:
            used[budget.name] = used.get(budget.name, 0) + budget.count(obj)
            if used[budget.name] > budget.cap:
                raise FieldError(prefix + (i, budget.field), budget.message)
