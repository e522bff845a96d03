"""A collision scene: validated objects (``planning.geometry.objects``) and, built on first
use, what the checker queries. Every per-shape step is a lookup in the shape registry
(``planning.geometry.registry``), so a registered shape takes part without changes here.

* **Primitives** (boxes, spheres, cylinders, capsules) keep their exact signed distance
  (their ``("point", shape)`` row of the pair table, ``planning.geometry.distance``).
* **Meshes and point clouds** become ball sets (``planning.geometry.spheres``): a mesh's
  triangles clipped to cubes of ``mesh_resolution`` mm (one ball per occupied cube); a point
  cloud's points grouped in cubes of its ``resolution`` (one ball per cube, inflated by the
  points' ``radius``). The distance to a ball set is exact (a k-d tree's nearest balls,
  widened until the answer is certain).
* **A distance grid** over the scene's bounding box: at each node, the distance to the
  nearest object (capped at ``GRID_CAP`` mm). As distances change by at most the step taken,
  ``grid value at the nearest node - distance to that node`` is a lower bound of the
  distance to the scene anywhere; the checker uses it to skip everything that is clearly far.

The exact stage (``planning.collision.exact``) uses the objects themselves (every triangle,
every point: each shape's ``exact`` geometry). Lengths in mm.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable
from typing import Any

import numpy as np

from kinematics.errors import FieldError

from ..geometry.balls import BallSet
from ..geometry.objects import MeshResolver, SceneObject, check_caps, parse_objects
from ..geometry.table import pair_functions, shape_kind, shape_names

__all__ = ["CollisionScene", "CompiledScene", "GRID_MAX_NODES", "GRID_CAP",
           "MESH_RESOLUTION", "OBJECT_TYPES"]

#: The object types a scene accepts: the built-in shapes (``shape_names()`` of
#: ``planning.geometry.registry`` lists the registered ones at any time).
OBJECT_TYPES = shape_names()

#: Most nodes of a scene's distance grid, and the largest distance (mm) it records.
GRID_MAX_NODES = 1 << 19
GRID_CAP = 600.0
#: Default cube size (mm) the balls of a scene mesh are built on.
MESH_RESOLUTION = 15.0


class CollisionScene:
    """A site's geometry for collision checking: ``objects`` (validated ``SceneObject``s,
    see ``planning.geometry.objects``), and ``mesh_resolution`` (mm) of the balls that
    stand for meshes in the sphere stage.

    Build it from API object dicts (``from_dicts``), a request body with ``objects`` and/or
    ``moveit`` (``from_request``) or a MoveIt PlanningScene (``from_moveit``); ``to_dicts``
    gives the objects back in the API format."""

    def __init__(self, objects: Iterable[SceneObject] = (),
                 mesh_resolution: float = MESH_RESOLUTION) -> None:
        self.objects: tuple[SceneObject, ...] = tuple(objects)
        check_caps(self.objects)
        if not (isinstance(mesh_resolution, int | float) and math.isfinite(mesh_resolution)
                and mesh_resolution > 0):
            raise FieldError(("mesh_resolution",), "mesh_resolution must be a positive number")
        self.mesh_resolution = float(mesh_resolution)
        self._compiled: CompiledScene | None = None
        self._exact: Any = None
        self._lock = threading.Lock()

    # ---- construction -----------------------------------------------------------------------
    @classmethod
    def from_dicts(cls, objects: Any, resolve_mesh: MeshResolver | None = None,
                   prefix: tuple = ("objects",)) -> CollisionScene:
        """From a list of object dicts (API format); ``FieldError`` at
        ``prefix + (i, field)``. ``resolve_mesh(name) -> (vertices, faces)`` finds stored
        meshes named by ``mesh`` objects."""
        return cls(parse_objects(objects, resolve_mesh, prefix))

    @classmethod
    def from_moveit(cls, planning_scene: Any, prefix: tuple = ()) -> CollisionScene:
        """From a MoveIt PlanningScene dict (metres; see ``planning.collision.moveit``)."""
        from .moveit import scene_from_moveit

        return cls.from_dicts(scene_from_moveit(planning_scene, prefix), None,
                              prefix + ("world", "collision_objects"))

    @classmethod
    def from_request(cls, data: Any, resolve_mesh: MeshResolver | None = None
                     ) -> CollisionScene:
        """From a request body ``{"objects": [...], "moveit": {...}}`` (either or both; the
        MoveIt objects come after the listed ones). Errors at ``("objects", i, ...)`` or
        ``("moveit", "world", "collision_objects", i, ...)``."""
        if not isinstance(data, dict):
            raise FieldError((), "a scene must be a JSON object")
        objects = parse_objects(data.get("objects") or [], resolve_mesh, ("objects",)) \
            if data.get("objects") is not None else ()
        if data.get("moveit") is not None:
            from .moveit import scene_from_moveit

            moved = parse_objects(scene_from_moveit(data["moveit"], ("moveit",)), None,
                                  ("moveit", "world", "collision_objects"))
            objects = tuple(objects) + tuple(moved)
        return cls(objects)

    def to_dicts(self) -> list[dict[str, Any]]:
        """The objects in the API format; ``from_dicts(to_dicts())`` gives the same scene
        (a stored mesh stays a reference by name)."""
        return [o.to_dict() for o in self.objects]

    def to_dict(self) -> dict[str, Any]:
        """``{"objects": to_dicts()}``."""
        return {"objects": self.to_dicts()}

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(o.id for o in self.objects)

    def __len__(self) -> int:
        return len(self.objects)

    def compiled(self) -> CompiledScene:
        """The query structures (built on first use, then kept; thread-safe)."""
        if self._compiled is None:
            with self._lock:
                if self._compiled is None:
                    self._compiled = CompiledScene(self.objects, self.mesh_resolution)
        return self._compiled

    def __getstate__(self):
        return {"objects": self.objects, "mesh_resolution": self.mesh_resolution,
                "compiled": self._compiled}

    def __setstate__(self, state):
        self.objects = state["objects"]
        self.mesh_resolution = state["mesh_resolution"]
        self._compiled = state["compiled"]
        self._exact = None
        self._lock = threading.Lock()


class CompiledScene:
    """What the checker queries (see the module docstring): ``object_distance`` (per object,
    exact for the sphere stage) and ``lower_bound`` (the grid)."""

    def __init__(self, objects: tuple[SceneObject, ...], mesh_resolution: float) -> None:
        self.n = len(objects)
        self.objects = objects
        self.ids = tuple(o.id for o in objects)
        #: ``(shape name, object indices, packed arrays)`` of the primitives, one per shape
        #: (their ``("point", shape)`` twin measures them all at once).
        self.groups: list[tuple[str, np.ndarray, tuple]] = []
        self.sets: list[tuple[int, BallSet]] = []
        members: dict[str, list[int]] = {}
        for i, o in enumerate(objects):
            kind = shape_kind(o.type)
            if kind.balls is not None:
                self.sets.append((i, BallSet(kind.balls(o, mesh_resolution))))
            else:
                members.setdefault(o.type, []).append(i)
        for name, idx in members.items():
            packed = shape_kind(name).pack([objects[i] for i in idx])
            self.groups.append((name, np.array(idx, dtype=np.intp), packed))
        self.bounds = [None] * self.n
        for name, idx, _ in self.groups:
            for i in idx:
                self.bounds[i] = shape_kind(name).bounds(objects[i])
        for i, bs in self.sets:
            self.bounds[i] = bs.bounds()
        self.lo = np.min([a for a, _ in self.bounds], axis=0) if self.n else np.zeros(3)
        self.hi = np.max([b for _, b in self.bounds], axis=0) if self.n else np.zeros(3)
        self._grid: Any = False

    @property
    def grid(self) -> Any:
        """The distance grid ``(lo, h, shape, values)`` (None for an empty scene), built on
        first use."""
        if self._grid is False:
            self._build_grid()
        return self._grid

    # ---- distances --------------------------------------------------------------------------
    def object_distance(self, P: np.ndarray) -> np.ndarray:
        """Signed distance ``(K, n)`` of points ``P (K, 3)`` to every object: exact for
        primitives, to the ball set for meshes and point clouds."""
        out = np.empty((len(P), self.n))
        for name, idx, packed in self.groups:
            out[:, idx] = pair_functions("point", name).twin(P, *packed)
        for i, s in self.sets:
            out[:, i] = s.distance(P)
        return out

    def _build_grid(self) -> None:
        """Distance (capped at ``GRID_CAP``) from each grid node to the nearest object,
        computed object by object on the nodes within ``GRID_CAP`` of it."""
        if self.n == 0:
            self._grid = None
            return
        lo, hi = self.lo - 1.0, self.hi + 1.0
        ext = hi - lo
        h = max(1.0, float(np.cbrt(ext.prod() / GRID_MAX_NODES)))
        shape = np.maximum(np.ceil(ext / h).astype(int) + 1, 2)
        while shape.prod() > GRID_MAX_NODES:
            h *= 1.05
            shape = np.maximum(np.ceil(ext / h).astype(int) + 1, 2)
        values = np.full(tuple(shape), GRID_CAP)
        for i, (a, b) in enumerate(self.bounds):
            i0 = np.clip(np.floor((a - GRID_CAP - lo) / h).astype(int), 0, shape - 1)
            i1 = np.clip(np.ceil((b + GRID_CAP - lo) / h).astype(int), 0, shape - 1)
            axes = [lo[k] + h * np.arange(i0[k], i1[k] + 1) for k in range(3)]
            X = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            d = np.empty(len(X))
            for s in range(0, len(X), 65536):
                d[s:s + 65536] = self._one(X[s:s + 65536], i)
            block = values[i0[0]:i1[0] + 1, i0[1]:i1[1] + 1, i0[2]:i1[2] + 1]
            np.minimum(block, d.reshape(block.shape), out=block)
        self._grid = (lo, h, shape, values.ravel())

    def _one(self, P: np.ndarray, i: int) -> np.ndarray:
        """Signed distance ``(K,)`` of points to object ``i``."""
        for name, idx, packed in self.groups:
            hit = np.flatnonzero(idx == i)
            if len(hit):
                k = int(hit[0])
                one = tuple(a[k:k + 1] for a in packed)
                return pair_functions("point", name).twin(P, *one)[:, 0]
        for j, s in self.sets:
            if j == i:
                return s.distance(P, cap=GRID_CAP)
        raise IndexError(i)

    def lower_bound(self, P: np.ndarray) -> np.ndarray:
        """A lower bound ``(...)`` of the signed distance from points ``P (..., 3)`` to the
        scene (``inf`` for an empty scene): the grid value at the nearest node minus the
        distance to it, and outside the scene's bounding box at least the distance to it."""
        shape_in = P.shape[:-1]
        if self.grid is None:
            return np.full(shape_in, np.inf)
        lo, h, shape, values = self.grid
        P = P.reshape(-1, 3)
        idx = np.rint((P - lo) / h).astype(np.intp)
        np.clip(idx, 0, shape - 1, out=idx)
        node = lo + idx * h
        flat = (idx[:, 0] * shape[1] + idx[:, 1]) * shape[2] + idx[:, 2]
        lb = values[flat] - np.sqrt(np.square(P - node).sum(1))
        gap = np.sqrt(np.square(np.maximum(np.maximum(self.lo - P, P - self.hi), 0.0)).sum(1))
        return np.where(gap > 0, np.maximum(lb, gap), lb).reshape(shape_in)

