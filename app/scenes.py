"""Stored scenes and meshes: where the service finds a site's geometry by id.

A scene is its list of objects in mm (``planning.collision``: boxes, spheres, cylinders,
capsules, meshes, point clouds); a MoveIt planning scene is converted to objects when it is
stored, so what is stored and answered is always the object list. Meshes are uploaded once
(``POST /meshes``) and referenced by id from scene objects; a mesh a scene uses cannot be
deleted. Both live in the service's store and are built into collision geometry on first use,
then kept; a restored store file is picked up as for robots (``Store.generation``).
"""

from __future__ import annotations

import io
import json
import logging
from typing import Any

import numpy as np

from .store import DuplicateError, Store, StoreMirror

__all__ = ["SceneRegistry", "SceneConflictError", "MeshInUseError", "mesh_bytes", "mesh_arrays"]

log = logging.getLogger(__name__)


class SceneConflictError(ValueError):
    """The scene or mesh id is taken."""


class MeshInUseError(ValueError):
    """A mesh cannot be deleted while a scene uses it."""


def mesh_bytes(vertices: np.ndarray, faces: np.ndarray) -> bytes:
    """A mesh as stored: an uncompressed ``.npz`` of float64 vertices (mm) and int32 faces."""
    buf = io.BytesIO()
    np.savez(buf, vertices=np.asarray(vertices, dtype=np.float64),
             faces=np.asarray(faces, dtype=np.int32))
    return buf.getvalue()


def mesh_arrays(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (V, 3) mm, faces (F, 3))`` of a stored mesh."""
    with np.load(io.BytesIO(data), allow_pickle=False) as z:
        return np.asarray(z["vertices"], dtype=np.float64), np.asarray(z["faces"], np.int64)


def _mesh_ids(objects: list[dict]) -> set[str]:
    return {str(o["mesh"]) for o in objects if o.get("type") == "mesh" and "mesh" in o}


class SceneRegistry(StoreMirror):
    """The scenes and meshes the service knows (all stored; none built in).

    Thread-safe as the robot registry: writers hold a lock and publish new dicts."""

    def __init__(self, store: Store | None = None) -> None:
        super().__init__(store)
        self._scenes: dict[str, dict] = {}
        self._meshes: dict[str, dict] = {}
        self._built: dict[str, Any] = {}
        self._mesh_cache: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._mesh_data: dict[str, bytes] = {}  # without a store only
        if store is not None:
            self._load()

    def _load(self) -> None:
        assert self._store is not None
        scenes: dict[str, dict] = {}
        for row in self._store.list_scenes():
            try:
                data = json.loads(row.scene_json)
            except ValueError as exc:
                log.error("skipping stored scene '%s': %s", row.id, exc)
                continue
            scenes[row.id] = {**data, "id": row.id, "created": row.created}
        meshes = {}
        for row in self._store.list_meshes():
            try:
                meshes[row.id] = {**json.loads(row.info_json), "id": row.id,
                                  "created": row.created}
            except ValueError as exc:
                log.error("skipping stored mesh '%s': %s", row.id, exc)
        self._scenes, self._meshes, self._built, self._mesh_cache = scenes, meshes, {}, {}

    def _reload(self) -> None:
        self._load()

    # ---- meshes -------------------------------------------------------------------------
    def mesh_ids(self) -> list[str]:
        self._refresh()
        return list(self._meshes)

    def mesh_info(self, mesh_id: str) -> dict:
        """What is known of mesh ``mesh_id`` (counts, bounds); ``KeyError`` if unknown."""
        self._refresh()
        return self._meshes[mesh_id]

    def add_mesh(self, mesh_id: str, vertices: np.ndarray, faces: np.ndarray,
                 filename: str) -> dict:
        """Store a mesh (mm); ``SceneConflictError`` if the id is taken."""
        self._refresh()
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        info = {"filename": filename, "vertices": int(len(vertices)),
                "triangles": int(len(faces)), "bounds": [lo.tolist(), hi.tolist()]}
        data = mesh_bytes(vertices, faces)
        with self._lock:
            if mesh_id in self._meshes:
                raise SceneConflictError(f"mesh id '{mesh_id}' is taken")
            if self._store is not None:
                try:
                    row = self._store.put_mesh(mesh_id, json.dumps(info), data)
                except DuplicateError:
                    raise SceneConflictError(f"mesh id '{mesh_id}' is taken") from None
                created = row.created
            else:
                self._mesh_data = {**self._mesh_data, mesh_id: data}
                created = None
            info = {**info, "id": mesh_id, "created": created}
            self._meshes = {**self._meshes, mesh_id: info}
        return info

    def mesh(self, mesh_id: str) -> tuple[np.ndarray, np.ndarray]:
        """``(vertices, faces)`` of a stored mesh; ``KeyError`` if unknown."""
        self._refresh()
        cached = self._mesh_cache.get(mesh_id)
        if cached is not None:
            return cached
        if mesh_id not in self._meshes:
            raise KeyError(mesh_id)
        data = (self._store.mesh_data(mesh_id) if self._store is not None
                else self._mesh_data[mesh_id])
        arrays = mesh_arrays(data)
        with self._lock:
            self._mesh_cache = {**self._mesh_cache, mesh_id: arrays}
        return arrays

    def remove_mesh(self, mesh_id: str) -> None:
        """Delete a mesh: ``KeyError`` if unknown, ``MeshInUseError`` naming the scenes that
        use it."""
        self._refresh()
        with self._lock:
            if mesh_id not in self._meshes:
                raise KeyError(mesh_id)
            users = [sid for sid, s in self._scenes.items()
                     if mesh_id in _mesh_ids(s.get("objects", []))]
            if users:
                raise MeshInUseError(f"mesh '{mesh_id}' is used by scene(s) "
                                     f"{', '.join(sorted(users))}; delete them first")
            if self._store is not None:
                self._store.delete_mesh(mesh_id)
            self._meshes = {k: v for k, v in self._meshes.items() if k != mesh_id}
            self._mesh_cache = {k: v for k, v in self._mesh_cache.items() if k != mesh_id}
            self._mesh_data = {k: v for k, v in self._mesh_data.items() if k != mesh_id}

    # ---- scenes -------------------------------------------------------------------------
    def ids(self) -> list[str]:
        self._refresh()
        return list(self._scenes)

    def describe(self, scene_id: str) -> dict:
        """The stored scene (id, name, objects, created); ``KeyError`` if unknown."""
        self._refresh()
        return self._scenes[scene_id]

    def build(self, data: dict) -> Any:
        """Collision geometry of a scene given as objects (and/or a MoveIt planning scene);
        ``FieldError`` naming the object at fault."""
        from planning.collision import CollisionScene

        return CollisionScene.from_request(data, self.mesh)

    def add(self, scene_id: str, data: dict) -> dict:
        """Validate, store and serve a scene; ``SceneConflictError`` if the id is taken."""
        self._refresh()
        if scene_id in self._scenes:
            raise SceneConflictError(f"scene id '{scene_id}' is taken")
        scene = self.build(data)
        stored = {"name": data.get("name") or scene_id, "objects": scene.to_dicts()}
        with self._lock:
            if scene_id in self._scenes:
                raise SceneConflictError(f"scene id '{scene_id}' is taken")
            created = None
            if self._store is not None:
                try:
                    row = self._store.put_scene(scene_id, json.dumps(stored, allow_nan=False))
                except DuplicateError:
                    raise SceneConflictError(f"scene id '{scene_id}' is taken") from None
                created = row.created
            entry = {**stored, "id": scene_id, "created": created}
            self._scenes = {**self._scenes, scene_id: entry}
            self._built = {**self._built, scene_id: scene}
        return entry

    def get(self, scene_id: str) -> Any:
        """The scene's collision geometry (built on first use); ``KeyError`` if unknown."""
        self._refresh()
        built = self._built.get(scene_id)
        if built is not None:
            return built
        entry = self._scenes[scene_id]
        scene = self.build({"objects": entry["objects"]})
        with self._lock:
            self._built = {**self._built, scene_id: scene}
        return scene

    def remove(self, scene_id: str) -> None:
        """Delete a scene; ``KeyError`` if unknown."""
        self._refresh()
        with self._lock:
            if scene_id not in self._scenes:
                raise KeyError(scene_id)
            if self._store is not None:
                self._store.delete_scene(scene_id)
            self._scenes = {k: v for k, v in self._scenes.items() if k != scene_id}
            self._built = {k: v for k, v in self._built.items() if k != scene_id}
