"""MoveIt planning scenes to and from scene objects.

``scene_from_moveit(d)`` reads a ``moveit_msgs/PlanningScene`` as its YAML or JSON parses
(metres) and returns object dicts in the API format (mm, ``planning.geometry.objects``):

* every ``world.collision_objects[i]``: its ``pose`` (absent: identity) composed with each of
  its ``primitives[j]`` / ``primitive_poses[j]`` and ``meshes[j]`` / ``mesh_poses[j]``:
  ``T_world_shape = T_world_object @ T_object_shape`` (older messages without ``pose`` give
  the shape poses in the world directly, which is the same with the identity);
* positions ``[x, y, z]`` or ``{x, y, z}``, orientations as quaternions ``[x, y, z, w]`` or
  ``{x, y, z, w}``, normalised (a zero quaternion is an error);
* ``box`` dimensions = full sides; ``sphere`` [radius]; ``cylinder`` [height, radius] (axis
  z, centred); ``cone`` [height, radius] becomes the cylinder of the same height and radius
  (shape_msgs centres a cone's bounding box on its origin, so the cylinder contains it:
  conservative); types may also be given by number (1 box, 2 sphere, 3 cylinder, 4 cone);
* ``meshes[j]``: ``shape_msgs/Mesh`` with ``vertices`` (points) and ``triangles``
  (``vertex_indices``), inline;
* one object per shape: its id is the collision object's ``id``, with ``/j`` (primitives)
  or ``/mesh{j}`` appended when the object has several shapes;
* ignored: ``robot_state`` (joint values come with each query), ``allowed_collision_matrix``
  (the robot's own pairs come from its SRDF), ``fixed_frame_transforms``, ``header`` frames
  (every pose is taken in the world frame = the robot's URDF root), ``subframe_poses``,
  colours; refused: ``planes`` (unbounded) and an ``operation`` other than ADD.

``scene_to_moveit(scene)`` writes a scene back (metres): primitives and meshes as they are, a
capsule as a cylinder and two spheres, a point cloud as one sphere per point.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from kinematics.errors import FieldError

__all__ = ["scene_from_moveit", "scene_to_moveit", "MM_PER_M"]

MM_PER_M = 1000.0
_TYPES = {1: "box", 2: "sphere", 3: "cylinder", 4: "cone"}
_DIMS = {"box": 3, "sphere": 1, "cylinder": 2, "cone": 2}


def _number(value: Any, loc: tuple, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(float(value)):
        raise FieldError(loc, f"{what} must be a finite number")
    return float(value)


def _xyz(value: Any, loc: tuple, keys: str) -> list[float]:
    if isinstance(value, dict):
        missing = [k for k in keys if k not in value]
        if missing:
            raise FieldError(loc, f"needs {', '.join(keys)} (missing {', '.join(missing)})")
        return [_number(value[k], loc + (k,), k) for k in keys]
    if isinstance(value, list | tuple) and len(value) == len(keys):
        return [_number(v, loc + (i,), keys[i]) for i, v in enumerate(value)]
    raise FieldError(loc, f"must be [{', '.join(keys)}] or {{{', '.join(keys)}}}")


def _pose(value: Any, loc: tuple) -> np.ndarray:
    """A geometry_msgs/Pose (metres) as a 4x4 in mm; identity for None."""
    T = np.eye(4)
    if value is None:
        return T
    if not isinstance(value, dict):
        raise FieldError(loc, "a pose is {position, orientation}")
    if value.get("position") is not None:
        T[:3, 3] = np.array(_xyz(value["position"], loc + ("position",), "xyz")) * MM_PER_M
    if value.get("orientation") is not None:
        x, y, z, w = _xyz(value["orientation"], loc + ("orientation",), "xyzw")
        n = math.sqrt(x * x + y * y + z * z + w * w)
        if n < 1e-9:
            raise FieldError(loc + ("orientation",), "the quaternion is zero: give a rotation "
                             "(x, y, z, w), e.g. [0, 0, 0, 1]")
        x, y, z, w = x / n, y / n, z / n, w / n
        T[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    return T


def _list(value: Any, loc: tuple, what: str) -> list:
    if value is None:
        return []
    if not isinstance(value, list | tuple):
        raise FieldError(loc, f"{what} must be a list")
    return list(value)


def scene_from_moveit(d: Any, prefix: tuple = ()) -> list[dict[str, Any]]:
    """Object dicts (API format, mm) of a MoveIt PlanningScene dict (metres); see the module
    docstring. ``FieldError`` at ``prefix + ("world", "collision_objects", i, ...)``."""
    if not isinstance(d, dict):
        raise FieldError(prefix, "a MoveIt planning scene must be an object (PlanningScene)")
    world = d.get("world")
    if world is None:
        return []
    if not isinstance(world, dict):
        raise FieldError(prefix + ("world",), "world must be an object (PlanningSceneWorld)")
    base = prefix + ("world", "collision_objects")
    out: list[dict[str, Any]] = []
    for i, co in enumerate(_list(world.get("collision_objects"), base, "collision_objects")):
        out.extend(_collision_object(co, base + (i,), i))
    return out


def _collision_object(co: Any, loc: tuple, i: int) -> list[dict[str, Any]]:
    if not isinstance(co, dict):
        raise FieldError(loc, "a collision object must be an object")
    op = co.get("operation", 0)
    if op not in (0, "0", "add", "ADD", b"\x00", None):
        raise FieldError(loc + ("operation",), "only ADD objects make a scene (operation 0)")
    if co.get("planes"):
        raise FieldError(loc + ("planes",), "planes are unbounded and not supported: use a "
                         "large thin box")
    oid = co.get("id")
    if oid is None or oid == "":
        oid = f"object{i}"
    if not isinstance(oid, str):
        raise FieldError(loc + ("id",), "id must be text")
    T_obj = _pose(co.get("pose"), loc + ("pose",))
    prims = _list(co.get("primitives"), loc + ("primitives",), "primitives")
    ppose = _list(co.get("primitive_poses"), loc + ("primitive_poses",), "primitive_poses")
    meshes = _list(co.get("meshes"), loc + ("meshes",), "meshes")
    mpose = _list(co.get("mesh_poses"), loc + ("mesh_poses",), "mesh_poses")
    for shapes, poses, name in ((prims, ppose, "primitive_poses"), (meshes, mpose, "mesh_poses")):
        if poses and len(poses) != len(shapes):
            raise FieldError(loc + (name,), f"{name} has {len(poses)} poses for "
                             f"{len(shapes)} shapes")
    several = len(prims) + len(meshes) > 1
    out = []
    for j, p in enumerate(prims):
        ploc = loc + ("primitives", j)
        T = T_obj @ _pose(ppose[j] if ppose else None, loc + ("primitive_poses", j))
        obj = _primitive(p, ploc)
        obj["id"] = f"{oid}/{j}" if several else oid
        obj["pose"] = T.tolist()
        out.append(obj)
    for j, m in enumerate(meshes):
        mloc = loc + ("meshes", j)
        T = T_obj @ _pose(mpose[j] if mpose else None, loc + ("mesh_poses", j))
        obj = _mesh(m, mloc)
        obj["id"] = f"{oid}/mesh{j}" if several else oid
        obj["pose"] = T.tolist()
        out.append(obj)
    return out


def _primitive(p: Any, loc: tuple) -> dict[str, Any]:
    if not isinstance(p, dict):
        raise FieldError(loc, "a primitive is {type, dimensions}")
    kind = p.get("type")
    kind = _TYPES.get(kind, kind) if isinstance(kind, int) and not isinstance(kind, bool) \
        else (kind.lower() if isinstance(kind, str) else kind)
    if kind not in _DIMS:
        raise FieldError(loc + ("type",), f"primitive type {p.get('type')!r} is not supported; "
                         "known: box (1), sphere (2), cylinder (3), cone (4)")
    dims = _list(p.get("dimensions"), loc + ("dimensions",), "dimensions")
    if len(dims) != _DIMS[kind]:
        raise FieldError(loc + ("dimensions",), f"a {kind} has {_DIMS[kind]} dimensions, got "
                         f"{len(dims)}")
    v = [_number(x, loc + ("dimensions", k), "a dimension") * MM_PER_M
         for k, x in enumerate(dims)]
    if any(x <= 0 for x in v):
        raise FieldError(loc + ("dimensions",), f"a {kind}'s dimensions must be positive")
    if kind == "box":
        return {"type": "box", "size": v}
    if kind == "sphere":
        return {"type": "sphere", "radius": v[0]}
    return {"type": "cylinder", "height": v[0], "radius": v[1]}


def _mesh(m: Any, loc: tuple) -> dict[str, Any]:
    if not isinstance(m, dict):
        raise FieldError(loc, "a mesh is {vertices, triangles}")
    verts = _list(m.get("vertices"), loc + ("vertices",), "vertices")
    tris = _list(m.get("triangles"), loc + ("triangles",), "triangles")
    if not verts or not tris:
        raise FieldError(loc, "a mesh needs vertices and triangles")
    V = [[c * MM_PER_M for c in _xyz(v, loc + ("vertices", k), "xyz")]
         for k, v in enumerate(verts)]
    F = []
    for k, t in enumerate(tris):
        idx = t.get("vertex_indices") if isinstance(t, dict) else t
        if not isinstance(idx, list | tuple) or len(idx) != 3 or not all(
                isinstance(x, int) and not isinstance(x, bool) and 0 <= x < len(V)
                for x in idx):
            raise FieldError(loc + ("triangles", k), f"a triangle is 3 vertex indices "
                             f"0..{len(V) - 1}")
        F.append(list(idx))
    return {"type": "mesh", "vertices": V, "faces": F}


# ---- back to MoveIt -----------------------------------------------------------------------
def _ros_pose(T: np.ndarray) -> dict[str, list[float]]:
    from scipy.spatial.transform import Rotation

    q = Rotation.from_matrix(np.asarray(T)[:3, :3]).as_quat()
    return {"position": (np.asarray(T)[:3, 3] / MM_PER_M).tolist(),
            "orientation": [float(x) for x in q]}


def scene_to_moveit(scene: Any, name: str = "") -> dict[str, Any]:
    """A ``CollisionScene`` as a MoveIt PlanningScene dict (metres; ``is_diff`` false):
    each object one collision object (its id) with identity ``pose`` and its shapes posed by
    ``primitive_poses`` / ``mesh_poses``."""
    objects = []
    for o in scene.objects:
        T = np.asarray(o.pose)
        co: dict[str, Any] = {"id": o.id, "header": {"frame_id": "world"},
                              "pose": _ros_pose(np.eye(4)), "operation": 0}
        prims, poses = [], []
        if o.type == "box":
            prims.append({"type": "box", "dimensions": [s / MM_PER_M for s in o.size]})
            poses.append(_ros_pose(T))
        elif o.type == "sphere":
            prims.append({"type": "sphere", "dimensions": [o.radius / MM_PER_M]})
            poses.append(_ros_pose(T))
        elif o.type == "cylinder":
            prims.append({"type": "cylinder",
                          "dimensions": [o.height / MM_PER_M, o.radius / MM_PER_M]})
            poses.append(_ros_pose(T))
        elif o.type == "capsule":
            a = T[:3, :3] @ np.asarray(o.a) + T[:3, 3]
            b = T[:3, :3] @ np.asarray(o.b) + T[:3, 3]
            for p in (a, b):
                prims.append({"type": "sphere", "dimensions": [o.radius / MM_PER_M]})
                poses.append(_ros_pose(_at(p)))
            L = float(np.linalg.norm(b - a))
            if L > 0:
                from ..geometry.distance import segment_frame

                F = segment_frame(a, b)
                prims.append({"type": "cylinder",
                              "dimensions": [L / MM_PER_M, o.radius / MM_PER_M]})
                poses.append(_ros_pose(F))
        elif o.type == "points":
            for p in o.world_points():
                prims.append({"type": "sphere", "dimensions": [o.radius / MM_PER_M]})
                poses.append(_ros_pose(_at(p)))
        elif o.type == "mesh":
            V = o.vertices * np.asarray(o.scale) / MM_PER_M
            co["meshes"] = [{"vertices": V.tolist(),
                             "triangles": [{"vertex_indices": [int(i) for i in f]}
                                           for f in o.faces]}]
            co["mesh_poses"] = [_ros_pose(T)]
        else:  # a registered shape with no MoveIt form: its bounding box, never smaller
            lo, hi = o.kind.bounds(o)
            prims.append({"type": "box", "dimensions": ((hi - lo) / MM_PER_M).tolist()})
            poses.append(_ros_pose(_at(0.5 * (lo + hi))))
        if prims:
            co["primitives"] = prims
            co["primitive_poses"] = poses
        objects.append(co)
    return {"name": name, "is_diff": False, "world": {"collision_objects": objects}}


def _at(p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T
