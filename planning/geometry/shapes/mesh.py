"""Mesh: a triangle surface, a stored mesh by name (``mesh``) or inline ``vertices`` and
``faces``; ``scale`` (one number or [sx, sy, sz]) multiplies the vertices. A mesh is its
surface, as FCL's triangle models: the sphere stage covers its triangles with balls
(``cover_triangles``), the exact stage uses every triangle. ``load_mesh_file`` reads
uploaded STL, OBJ and PLY files."""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.model import MAX_LENGTH_MM

from ..fields import array, number, vector
from ..registry import KERNEL_CODES, Budget, ShapeKind, register_shape
from ._common import fcl_object

__all__ = ["MAX_MESH_TRIANGLES", "MAX_SCENE_TRIANGLES", "MESH_FILE_TYPES", "load_mesh_file"]

#: Most triangles of one mesh (an uploaded file or an inline mesh).
MAX_MESH_TRIANGLES = 200_000
#: Most triangles of all meshes of one scene together.
MAX_SCENE_TRIANGLES = 1_000_000
#: File types ``load_mesh_file`` reads (by the file name's extension).
MESH_FILE_TYPES = ("stl", "obj", "ply")


def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    scale_value = data.get("scale", 1.0)
    if isinstance(scale_value, list | tuple):
        scale = vector(scale_value, loc + ("scale",), "scale", True)
    else:
        s = number(scale_value, loc + ("scale",), "scale")
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
    V = array(V, loc + ("vertices",), "vertices", 3, float, 3 * MAX_MESH_TRIANGLES + 3)
    F = array(F, loc + ("faces",), "faces", 3, int, MAX_MESH_TRIANGLES)
    if F.min() < 0 or F.max() >= len(V):
        raise FieldError(loc + ("faces",), f"faces must index the {len(V)} vertices "
                         f"(0 to {len(V) - 1})")
    if np.abs(V * np.asarray(scale)).max() > MAX_LENGTH_MM:
        raise FieldError(loc + ("scale",), f"scaled vertices must be within "
                         f"{MAX_LENGTH_MM:g} mm")
    return {"mesh": name, "scale": scale, "vertices": V, "faces": F}


def to_dict(o) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if o.mesh is not None:
        out["mesh"] = o.mesh
    else:
        out["vertices"] = o.vertices.tolist()
        out["faces"] = o.faces.tolist()
    if o.scale != (1.0, 1.0, 1.0):
        out["scale"] = list(o.scale)
    return out


def balls(o, resolution: float) -> np.ndarray:
    """Balls covering the world triangles, one per cube of side ``resolution`` they
    cross."""
    from ..spheres import cover_triangles

    V = o.world_vertices()
    return cover_triangles(V[o.faces], resolution)


def exact(o) -> tuple:
    import fcl

    V = o.vertices * np.asarray(o.scale)
    m = fcl.BVHModel()
    m.beginModel(len(V), len(o.faces))
    m.addSubModel(np.ascontiguousarray(V, dtype=float),
                  np.ascontiguousarray(o.faces, dtype=np.int64))
    m.endModel()
    return fcl_object(m, np.asarray(o.pose, dtype=float))


def path_cover(o) -> list[dict[str, Any]]:
    """Its axis-aligned bounding box (a flat mesh, a wall of two triangles, still gets a
    box: 1 µm thick)."""
    V = o.world_vertices()
    lo, hi = V.min(axis=0), V.max(axis=0)
    pad = 1e-3
    return [{"type": "box", "lower": (lo - pad).tolist(), "upper": (hi + pad).tolist()}]


KIND = register_shape(ShapeKind(
    name="mesh", required=(), optional=("mesh", "vertices", "faces", "scale"), parse=parse,
    to_dict=to_dict, balls=balls, code=KERNEL_CODES["balls"], exact=exact,
    path_cover=path_cover,
    budget=Budget("triangles", lambda o: len(o.faces), MAX_SCENE_TRIANGLES, "mesh",
                  f"the scene's meshes hold more than {MAX_SCENE_TRIANGLES} triangles "
                  f"together")))


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
