"""Mesh files: finding a URDF's mesh reference in the upload, loading it, storing it.

Where a reference is looked for (first hit wins; a name that matches only ignoring case is
taken when it is the only such one):

* ``package://PKG/REL`` (and Gazebo's ``model://PKG/REL``): ``PKG/REL`` in the URDF's folder,
  ``PKG/REL`` at the archive root, ``REL`` in the URDF's folder, ``REL`` at the root (the
  package folder stripped), then ``REL`` in every folder named ``PKG``, shallowest first (a
  ROS workspace layout: ``src/PKG/urdf/robot.urdf`` beside ``src/PKG/meshes/...``).
* a relative path: in the URDF's folder, then at the archive root.
* ``file:///abs/path`` or ``/abs/path`` (a path on the author's machine): its trailing parts,
  longest first, in the URDF's folder then at the root — ``/home/me/robot/meshes/a.stl``
  finds ``meshes/a.stl``.
* other schemes (``http://``...) are refused: nothing is fetched.

Formats: STL, OBJ, PLY and DAE (COLLADA, read by pycollada), loaded with trimesh; a file
that does not load, or loads without triangles, is an error naming it. Vertices are scaled
by the URDF ``<mesh scale>`` and converted to mm; a mirroring scale (negative product) turns
the faces over so they keep facing out.
"""

from __future__ import annotations

import importlib.util
import io
import re

import numpy as np

from ..errors import FieldError, Loc
from ._archive import Upload, join_inside
from ._limits import ImportLimits
from ._robot import MeshData

__all__ = ["MESH_SUFFIXES", "mesh_candidates", "resolve_mesh", "load_mesh", "mesh_to_bytes",
           "mesh_from_bytes"]

MESH_SUFFIXES = ("stl", "obj", "ply", "dae")
_MM_PER_M = 1000.0
_DECLARATION = re.compile(rb"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)


def mesh_candidates(ref: str, urdf_dir: str, upload: Upload) -> list[str]:
    """Where ``ref`` is looked for, in order (paths inside the archive; see the module)."""
    ref = ref.strip()
    out: list[str | None] = []
    lower = ref.lower()
    if lower.startswith(("package://", "model://")):
        rest = ref.split("://", 1)[1]
        package, _, relative = rest.partition("/")
        out += [join_inside(urdf_dir, rest), join_inside("", rest),
                join_inside(urdf_dir, relative), join_inside("", relative)]
        out += [join_inside(folder, relative) for folder in upload.folders_named(package)]
    else:
        path = ref[len("file://"):] if lower.startswith("file://") else ref
        path = path.replace("\\", "/")
        absolute = path.startswith("/") or re.match(r"^[A-Za-z]:/", path) is not None
        if not absolute:
            out += [join_inside(urdf_dir, path), join_inside("", path)]
        parts = [p for p in path.split("/") if p not in ("", ".", "..")]
        for k in range(len(parts)):
            suffix = "/".join(parts[k:])
            out += [join_inside(urdf_dir, suffix), join_inside("", suffix)]
    seen: list[str] = []
    for candidate in out:
        if candidate is not None and candidate not in seen:
            seen.append(candidate)
    return seen


def resolve_mesh(ref: str, urdf_dir: str, upload: Upload, loc: Loc, link: str) -> str:
    """The archive member ``ref`` names; ``FieldError(loc, ...)`` naming the link and the
    file when it is missing (or cannot be in a bare URDF)."""
    if not ref.strip():
        raise FieldError(loc, f"link '{link}': empty mesh filename")
    scheme = ref.split("://", 1)[0].lower() if "://" in ref else ""
    if scheme not in ("", "package", "model", "file"):
        raise FieldError(loc, f"link '{link}': mesh '{ref}' is a remote file ({scheme}://); "
                              "meshes must be in the uploaded archive")
    if upload.kind == "urdf":
        raise FieldError(loc, f"link '{link}' references the mesh file '{ref}', but a bare "
                              "URDF carries no meshes: upload a .zip or .tar.gz archive "
                              "holding the URDF and its mesh files")
    candidates = mesh_candidates(ref, urdf_dir, upload)
    for candidate in candidates:
        found = upload.find(candidate)
        if found is not None:
            return found
    shown = ", ".join(candidates[:6]) + (" ..." if len(candidates) > 6 else "")
    raise FieldError(loc, f"link '{link}': mesh file '{ref}' is not in the archive "
                          f"(looked for {shown})")


def load_mesh(data: bytes, name: str, scale: np.ndarray, loc: Loc, link: str,
              limits: ImportLimits) -> MeshData:
    """Load the mesh file ``name`` (its bytes ``data``), scaled by ``scale (3,)`` and
    converted from m to mm; ``FieldError(loc, ...)`` naming the link and the file when it is
    not a mesh of a supported format or exceeds ``limits.max_mesh_triangles``."""
    suffix = name.rsplit(".", 1)[-1].lower() if "." in name.rsplit("/", 1)[-1] else ""
    if suffix not in MESH_SUFFIXES:
        raise FieldError(loc, f"link '{link}': mesh file '{name}' has an unsupported format "
                              f"('.{suffix}'); use STL, OBJ, PLY or DAE")
    if suffix == "dae":
        if _DECLARATION.search(data) is not None:
            raise FieldError(loc, f"link '{link}': mesh file '{name}' declares a DOCTYPE or "
                                  "entities; these are not accepted")
        if importlib.util.find_spec("collada") is None:
            raise FieldError(loc, f"link '{link}': reading the DAE (COLLADA) mesh '{name}' "
                                  "needs pycollada, which this server lacks; convert it to "
                                  "STL or OBJ")
    import trimesh  # a heavy import, needed only here

    try:
        mesh = trimesh.load(io.BytesIO(data), file_type=suffix, force="mesh")
    except Exception as exc:  # noqa: BLE001 - any parser failure means "not a mesh"
        detail = f"{type(exc).__name__}: {exc}"[:200]
        raise FieldError(loc, f"link '{link}': mesh file '{name}' is not a readable "
                              f"{suffix.upper()} mesh ({detail})") from None
    faces = getattr(mesh, "faces", None)
    if not isinstance(mesh, trimesh.Trimesh) or faces is None or len(faces) == 0:
        raise FieldError(loc, f"link '{link}': mesh file '{name}' holds no triangles (not a "
                              f"{suffix.upper()} mesh?)")
    if len(faces) > limits.max_mesh_triangles:
        raise FieldError(loc, f"link '{link}': mesh file '{name}' has {len(faces):,} "
                              f"triangles; at most {limits.max_mesh_triangles:,} per mesh")
    vertices = np.asarray(mesh.vertices, dtype=float) * (np.asarray(scale) * _MM_PER_M)
    if not np.all(np.isfinite(vertices)):
        raise FieldError(loc, f"link '{link}': mesh file '{name}' has non-finite vertices")
    faces = np.asarray(faces, dtype=np.int64)
    if np.prod(np.sign(scale)) < 0:
        faces = np.ascontiguousarray(faces[:, ::-1])
    return _frozen_mesh(vertices, faces)


def _frozen_mesh(vertices: np.ndarray, faces: np.ndarray) -> MeshData:
    vertices = np.ascontiguousarray(vertices, dtype=float)
    faces = np.ascontiguousarray(faces, dtype=np.int64)
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return MeshData(vertices=vertices, faces=faces)


def mesh_to_bytes(mesh: MeshData) -> bytes:
    """A mesh as bytes: an uncompressed ``.npz`` (numpy zip) holding ``vertices`` ``(V, 3)``
    little-endian float64 mm and ``faces`` ``(F, 3)`` little-endian int32. Lossless:
    ``mesh_from_bytes(mesh_to_bytes(m))`` equals ``m`` exactly."""
    vertices = np.asarray(mesh.vertices, dtype="<f8")
    faces = np.asarray(mesh.faces)
    if faces.size and (faces.min() < 0 or faces.max() >= 2**31 - 1):
        raise ValueError("face indices do not fit in int32")
    buffer = io.BytesIO()
    np.savez(buffer, vertices=vertices, faces=faces.astype("<i4"))
    return buffer.getvalue()


def mesh_from_bytes(data: bytes) -> MeshData:
    """The mesh ``mesh_to_bytes`` wrote; ``ValueError`` when ``data`` is not one."""
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            if set(npz.files) != {"vertices", "faces"}:
                raise ValueError(f"expected arrays 'vertices' and 'faces', got {npz.files}")
            vertices = npz["vertices"]
            faces = npz["faces"]
    except ValueError:
        raise
    except Exception as exc:  # noqa: BLE001 - zip or header damage of any kind
        raise ValueError(f"not a stored mesh: {exc}") from None
    if vertices.dtype != np.dtype("<f8") or vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError("vertices must be (V, 3) float64")
    if faces.dtype != np.dtype("<i4") or faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError("faces must be (F, 3) int32")
    if not np.all(np.isfinite(vertices)):
        raise ValueError("vertices must be finite")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise ValueError("face indices out of range")
    return _frozen_mesh(vertices.astype(float), faces.astype(np.int64))
