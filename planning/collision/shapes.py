"""Scene objects for collision checking: their API format, validation and mesh files.

An object is a dict ``{"type": ..., "id": optional name, "pose": 4x4 (default identity),
...}`` with lengths in mm and the pose ``T_world_object`` (row-major nested lists):

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

Invalid input raises ``FieldError(("objects", i, field), message)``. Caps (``MAX_OBJECTS``,
``MAX_POINTS``, ``MAX_MESH_TRIANGLES``, ``MAX_SCENE_TRIANGLES``) bound the work one scene
can ask for.
"""

from __future__ import annotations

import io
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.model import MAX_LENGTH_MM, MAX_NAME_LENGTH
from kinematics.transforms import rigidity_error

__all__ = [
    "OBJECT_TYPES",
    "MAX_OBJECTS",
    "MAX_POINTS",
    "MAX_MESH_TRIANGLES",
    "MAX_SCENE_TRIANGLES",
    "MESH_FILE_TYPES",
    "SceneObject",
    "MeshResolver",
    "parse_object",
    "load_mesh_file",
]

#: The object types a scene accepts.
OBJECT_TYPES = ("box", "sphere", "cylinder", "capsule", "mesh", "points")
#: Most objects in one scene.
MAX_OBJECTS = 1000
#: Most points of all ``points`` objects of one scene together.
MAX_POINTS = 200_000
#: Most triangles of one mesh (an uploaded file or an inline mesh).
MAX_MESH_TRIANGLES = 200_000
#: Most triangles of all meshes of one scene together.
MAX_SCENE_TRIANGLES = 1_000_000
#: File types ``load_mesh_file`` reads (by the file name's extension).
MESH_FILE_TYPES = ("stl", "obj", "ply")
#: Largest deviation from a rigid transform accepted in a pose (``rigidity_error``).
POSE_TOLERANCE = 1e-6

#: A stored mesh by name -> ``(vertices (V, 3) mm, faces (F, 3))``; raises ``KeyError`` for
#: an unknown name.
MeshResolver = Callable[[str], tuple[np.ndarray, np.ndarray]]

_FIELDS = {
    "box": ("size",),
    "sphere": ("radius",),
    "cylinder": ("radius", "height"),
    "capsule": ("a", "b", "radius"),
    "mesh": (),
    "points": ("points", "radius"),
}
_OPTIONAL = {"mesh": ("mesh", "vertices", "faces", "scale"), "points": ("resolution",)}
_COMMON = ("type", "id", "pose")


@dataclass(frozen=True, eq=False)
class SceneObject:
    """One validated scene object (see the module docstring). Arrays are read-only;
    ``pose`` is ``T_world_object (4, 4)``. For ``mesh``: ``vertices (V, 3)`` as given
    (before ``scale``), ``faces (F, 3)``, ``mesh`` the stored mesh's name or None for an
    inline mesh. For ``points``: ``points (N, 3)`` in the object frame."""

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

    def world_vertices(self) -> np.ndarray:
        """A mesh's vertices ``(V, 3)`` in the world frame, mm (``scale`` applied)."""
        V = self.vertices * np.asarray(self.scale)
        return V @ self.pose[:3, :3].T + self.pose[:3, 3]

    def world_points(self) -> np.ndarray:
        """A point cloud's points ``(N, 3)`` in the world frame, mm."""
        return self.points @ self.pose[:3, :3].T + self.pose[:3, 3]

    def to_dict(self) -> dict[str, Any]:
        """The object in the API format (``parse_object`` reads it back to the same
        object). A stored mesh is written by name, an inline one with its arrays."""
        out: dict[str, Any] = {"type": self.type, "id": self.id, "pose": self.pose.tolist()}
        if self.type == "box":
            out["size"] = list(self.size)
        elif self.type in ("sphere", "cylinder"):
            out["radius"] = self.radius
            if self.type == "cylinder":
                out["height"] = self.height
        elif self.type == "capsule":
            out.update(a=list(self.a), b=list(self.b), radius=self.radius)
        elif self.type == "mesh":
            if self.mesh is not None:
                out["mesh"] = self.mesh
            else:
                out["vertices"] = self.vertices.tolist()
                out["faces"] = self.faces.tolist()
            if self.scale != (1.0, 1.0, 1.0):
                out["scale"] = list(self.scale)
        else:
            out.update(points=self.points.tolist(), radius=self.radius,
                       resolution=self.resolution)
        return out


# ---- validation ---------------------------------------------------------------------------
def _number(value: Any, loc: tuple, what: str, positive: bool = True) -> float:
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


def _vector(value: Any, loc: tuple, what: str, positive: bool = False
            ) -> tuple[float, float, float]:
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise FieldError(loc, f"{what} must be a list of 3 numbers")
    return tuple(_number(v, loc + (k,), what, positive) for k, v in enumerate(value))


def _array(value: Any, loc: tuple, what: str, cols: int, dtype: type, cap: int) -> np.ndarray:
    """A ``(n, cols)`` array from nested lists (or an array), at most ``cap`` rows."""
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


def parse_object(data: Any, index: int, resolve_mesh: MeshResolver | None = None,
                 prefix: tuple = ("objects",)) -> SceneObject:
    """Validate one object dict; errors at ``prefix + (index, field)``."""
    loc = prefix + (index,)
    if not isinstance(data, dict):
        raise FieldError(loc, "each object must be a JSON object with a 'type'")
    kind = data.get("type")
    if kind not in OBJECT_TYPES:
        what = "is missing" if kind is None else f"'{kind}' is not a known type"
        raise FieldError(loc + ("type",), f"type {what}; known types: {', '.join(OBJECT_TYPES)}")
    allowed = set(_COMMON) | set(_FIELDS[kind]) | set(_OPTIONAL.get(kind, ()))
    for key in data:
        if key not in allowed:
            raise FieldError(loc + (str(key),), f"unknown field for a {kind}; a {kind} has "
                             f"{', '.join(sorted(allowed))}")
    for key in _FIELDS[kind]:
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
    common = {"type": kind, "id": oid, "pose": pose}
    if kind == "box":
        return SceneObject(size=_vector(data["size"], loc + ("size",), "size", True), **common)
    if kind in ("sphere", "cylinder", "capsule", "points"):
        radius = _number(data["radius"], loc + ("radius",), "radius")
    if kind == "sphere":
        return SceneObject(radius=radius, **common)
    if kind == "cylinder":
        return SceneObject(radius=radius,
                           height=_number(data["height"], loc + ("height",), "height"),
                           **common)
    if kind == "capsule":
        return SceneObject(a=_vector(data["a"], loc + ("a",), "a"),
                           b=_vector(data["b"], loc + ("b",), "b"), radius=radius, **common)
    if kind == "points":
        pts = _array(data["points"], loc + ("points",), "points", 3, float, MAX_POINTS)
        res = data.get("resolution")
        res = radius if res is None else _number(res, loc + ("resolution",), "resolution")
        return SceneObject(points=pts, radius=radius, resolution=res, **common)
    return _parse_mesh(data, loc, resolve_mesh, common)


def _parse_mesh(data: dict, loc: tuple, resolve_mesh: MeshResolver | None,
                common: dict) -> SceneObject:
    scale_value = data.get("scale", 1.0)
    if isinstance(scale_value, list | tuple):
        scale = _vector(scale_value, loc + ("scale",), "scale", True)
    else:
        s = _number(scale_value, loc + ("scale",), "scale")
        scale = (s, s, s)
    name = data.get("mesh")
    if name is not None:
        if "vertices" in data or "faces" in data:
            raise FieldError(loc + ("mesh",), "give either 'mesh' (a stored mesh's name) or "
                             "inline 'vertices' and 'faces', not both")
        if not isinstance(name, str) or not name:
            raise FieldError(loc + ("mesh",), "mesh must be the name of a stored mesh")
        if resolve_mesh is None:
            raise FieldError(loc + ("mesh",), "no mesh store here: give inline 'vertices' "
                             "and 'faces'")
        try:
            V, F = resolve_mesh(name)
        except KeyError:
            raise FieldError(loc + ("mesh",), f"no stored mesh named '{name}'") from None
        V = np.asarray(V, dtype=float)
        F = np.asarray(F, dtype=np.int64)
    else:
        if "vertices" not in data or "faces" not in data:
            raise FieldError(loc + ("mesh",), "a mesh needs 'mesh' (a stored mesh's name) or "
                             "inline 'vertices' and 'faces'")
        V = data["vertices"]
        F = data["faces"]
    V = _array(V, loc + ("vertices",), "vertices", 3, float, 3 * MAX_MESH_TRIANGLES + 3)
    F = _array(F, loc + ("faces",), "faces", 3, int, MAX_MESH_TRIANGLES)
    if F.min() < 0 or F.max() >= len(V):
        raise FieldError(loc + ("faces",), f"faces must index the {len(V)} vertices "
                         f"(0 to {len(V) - 1})")
    if np.abs(V * np.asarray(scale)).max() > MAX_LENGTH_MM:
        raise FieldError(loc + ("scale",), f"scaled vertices must be within "
                         f"{MAX_LENGTH_MM:g} mm")
    return SceneObject(mesh=name, scale=scale, vertices=V, faces=F, **common)


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
    """Unique ids, ``MAX_POINTS`` and ``MAX_SCENE_TRIANGLES`` over the scene."""
    seen: dict[str, int] = {}
    points = triangles = 0
    for i, obj in enumerate(objects):
        if obj.id in seen:
            raise FieldError(prefix + (i, "id"), f"id '{obj.id}' is already used by object "
                             f"{seen[obj.id]}")
        seen[obj.id] = i
        if obj.type == "points":
            points += len(obj.points)
            if points > MAX_POINTS:
                raise FieldError(prefix + (i, "points"), f"the scene's point clouds hold more "
                                 f"than {MAX_POINTS} points together")
        elif obj.type == "mesh":
            triangles += len(obj.faces)
            if triangles > MAX_SCENE_TRIANGLES:
                raise FieldError(prefix + (i, "mesh"), f"the scene's meshes hold more than "
                                 f"{MAX_SCENE_TRIANGLES} triangles together")


# ---- mesh files ---------------------------------------------------------------------------
def load_mesh_file(data: bytes, filename: str) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh from an STL, OBJ or PLY file's bytes (the type from the file
    name's extension): ``(vertices (V, 3) float, faces (F, 3) int64)`` in the file's units
    (taken as mm; a scene object's ``scale`` converts others). ``FieldError`` at
    ``("file",)`` when the bytes are not a triangle mesh of that type or exceed
    ``MAX_MESH_TRIANGLES``. Reads with trimesh, merging duplicate vertices."""
    ext = filename.rsplit(".", 1)[-1].lower() if "." in filename else ""
    if ext not in MESH_FILE_TYPES:
        raise FieldError(("file",), f"'{filename}' is not a mesh file: use "
                         f"{', '.join('.' + e for e in MESH_FILE_TYPES)}")
    import trimesh

    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=ext, force="mesh", process=True)
    except Exception as exc:  # noqa: BLE001 - any parser failure is the file's fault
        raise FieldError(("file",), f"'{filename}' could not be read as {ext.upper()}: "
                         f"{type(exc).__name__}") from None
    faces = getattr(loaded, "faces", None)
    vertices = getattr(loaded, "vertices", None)
    if faces is None or vertices is None or len(faces) == 0:
        raise FieldError(("file",), f"'{filename}' holds no triangles")
    if len(faces) > MAX_MESH_TRIANGLES:
        raise FieldError(("file",), f"'{filename}' has {len(faces)} triangles, more than "
                         f"the cap of {MAX_MESH_TRIANGLES}")
    V = np.array(vertices, dtype=float)
    F = np.array(faces, dtype=np.int64)
    if not np.all(np.isfinite(V)) or np.abs(V).max() > MAX_LENGTH_MM:
        raise FieldError(("file",), f"'{filename}' has vertices that are not finite or "
                         f"beyond {MAX_LENGTH_MM:g}")
    return V, F
