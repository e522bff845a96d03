"""Where the service finds robot models by id: the built-ins, the custom robots and the robots
imported from URDF (with their links, geometry and meshes), and each robot's collision model."""

from __future__ import annotations

import json
import logging
import uuid
from typing import Any

from kinematics.library import builtin_models
from kinematics.model import RobotModel
from kinematics.rigs import BUILTIN_RIG_IDS, Rig, builtin_rig

from .collision_models import build_collision
from .store import DuplicateError, Store, StoreMirror

__all__ = ["RobotRegistry", "RobotConflictError", "ReadOnlyRobotError"]

log = logging.getLogger(__name__)


#: Key of an imported robot's built collision model among its stored files (mesh keys have
#: no dot, so it cannot clash with one).
COLLISION_FILE = "collision.model"



class RobotConflictError(ValueError):
    """The id is a built-in's or already taken by a custom robot."""

    def __init__(self, robot_id: str, message: str):
        super().__init__(message)
        self.robot_id = robot_id


class ReadOnlyRobotError(ValueError):
    """Built-in robots cannot be changed or removed."""


class CollisionNotReady(RuntimeError):
    """An imported robot's collision model is still being built."""

    def __init__(self, robot_id: str, message: str):
        super().__init__(message)
        self.robot_id = robot_id


class RobotRegistry(StoreMirror):
    """The robots the service knows: the built-ins (read-only) and custom robots.

    Custom robots live in ``store`` and are parsed once into ``RobotModel``s kept in memory
    (all loaded at construction, and again when the store starts using another file, e.g. a
    restored backup). Without a store, custom robots last as long as the registry.
    Thread-safe: writers (and a reload) hold a lock and publish a new dict, so readers
    otherwise never lock and never see a half-made change.
    """

    def __init__(self, store: Store | None = None) -> None:
        self.rigs: dict[str, Rig] = {rid: builtin_rig(rid) for rid in BUILTIN_RIG_IDS}
        # Each rig's arms are robots too (mount applied), so every endpoint works on them.
        self._builtin = builtin_models() | {
            arm.id: arm for rig in self.rigs.values() for arm in rig.arms.values()
        }
        super().__init__(store)
        # Imported robots: the description JSON of each (meshes are read from the store on
        # first use and kept in ``_imported``; ``_collision`` caches collision models).
        self._descriptions: dict[str, dict] = {}
        self._imported: dict[str, Any] = {}
        self._collision: dict[str, Any] = {}
        self._custom: dict[str, RobotModel] = self._load() if store is not None else {}

    def _load(self) -> dict[str, RobotModel]:
        """Every stored robot that still parses; a bad row is logged and skipped."""
        assert self._store is not None
        custom: dict[str, RobotModel] = {}
        descriptions: dict[str, dict] = {}
        for row in self._store.list_robots():
            try:
                model = RobotModel.from_dict(json.loads(row.model_json))
                description = (json.loads(row.description_json)
                               if row.description_json is not None else None)
            except Exception as exc:  # any bad row (bad JSON, invalid model): keep starting
                log.error("skipping stored robot '%s': %s", row.id, exc)
                continue
            if model.id != row.id or row.id in self._builtin:
                log.error("skipping stored robot '%s': id clash (model id '%s')", row.id,
                          model.id)
                continue
            custom[row.id] = model
            if description is not None:
                descriptions[row.id] = description
        self._descriptions = descriptions
        self._imported = {}
        self._collision = {}
        return custom

    def _reload(self) -> None:
        self._custom = self._load()

    def _current(self) -> dict[str, RobotModel]:
        """The custom robots, loaded again first when the store has moved on to another file
        or works again after it could not be read (``StoreMirror``)."""
        if self._refresh():
            log.info("custom robots loaded again from the store (%d)", len(self._custom))
        return self._custom

    def ids(self) -> list[str]:
        """Built-in ids first, then custom ones in the order they were added."""
        return [*self._builtin, *self._current()]

    def get(self, robot_id: str) -> RobotModel:
        """The model ``robot_id``; ``KeyError`` if unknown."""
        model = self._builtin.get(robot_id)
        if model is None:
            model = self._current().get(robot_id)
        if model is None:
            raise KeyError(robot_id)
        return model

    def is_builtin(self, robot_id: str) -> bool:
        return robot_id in self._builtin

    def all(self) -> list[RobotModel]:
        """Every model, in the order of ``ids()``."""
        return [*self._builtin.values(), *self._current().values()]

    def add(self, model: RobotModel) -> None:
        """Store and serve a custom robot; ``RobotConflictError`` if its id is taken."""
        self._add(model)

    def add_imported(self, robot: Any, mesh_files: dict[str, bytes]) -> None:
        """Store and serve a robot imported from URDF (``kinematics.urdf_import``), its
        description and mesh files in one transaction; ``RobotConflictError`` if its id is
        taken."""
        self._add(robot.model, robot, mesh_files)

    def _add(self, model: RobotModel, robot: Any = None,
             mesh_files: dict[str, bytes] | None = None) -> None:
        if model.id in self._builtin:
            raise RobotConflictError(model.id, f"'{model.id}' is a built-in robot id")
        # allow_nan=False: a model whose extra fields hold NaN could not be served as JSON.
        text = json.dumps(model.to_dict(), allow_nan=False)
        description = robot.to_dict() if robot is not None else None
        self._current()
        with self._lock:
            if model.id in self._custom:
                raise RobotConflictError(model.id, f"robot id '{model.id}' is taken")
            if self._store is not None:
                try:
                    self._store.put_robot(
                        model.id, text, meshes=mesh_files,
                        description_json=None if description is None
                        else json.dumps(description, allow_nan=False))
                except DuplicateError:  # e.g. a stored row that no longer parses
                    raise RobotConflictError(
                        model.id, f"robot id '{model.id}' is taken in the store"
                    ) from None
            if robot is not None:
                self._descriptions = {**self._descriptions, model.id: description}
                self._imported = {**self._imported, model.id: robot}
            self._custom = {**self._custom, model.id: model}

    def imported(self, robot_id: str) -> Any | None:
        """The imported robot ``robot_id`` (``kinematics.urdf_import.ImportedRobot``: links,
        geometry, meshes), None for built-in and model-JSON robots; ``KeyError`` if unknown."""
        model = self.get(robot_id)
        robot = self._imported.get(robot_id)
        if robot is not None and robot.model is model:
            return robot
        description = self._descriptions.get(robot_id)
        if description is None:
            return None
        from kinematics.urdf_import import ImportedRobot, mesh_from_bytes

        files = self._store.robot_meshes(robot_id) if self._store is not None else {}
        robot = ImportedRobot.from_dict(description, {k: mesh_from_bytes(v)
                                                      for k, v in files.items()
                                                      if k != COLLISION_FILE})
        with self._lock:
            self._imported = {**self._imported, robot_id: robot}
        return robot

    def collision_model(self, robot_id: str) -> Any:
        """The robot's collision model (``planning.collision.RobotCollisionModel``): from the
        URDF's collision geometry for imported robots, link capsules for the others; built
        once and kept (an imported robot's in the store too). ``KeyError`` if unknown."""
        return self.collision_entry(robot_id)[0]

    def collision_entry(self, robot_id: str) -> tuple[Any, str]:
        """``(collision model, token)``: the token names this build of the model, so a worker
        process may keep what it derived from it (exact geometry) between requests. Builds
        the model here when it is neither kept nor stored (seconds for an imported robot:
        ``build_collision`` does it in a worker process instead)."""
        entry = self.stored_collision(robot_id)
        if entry is not None:
            return entry
        # Only an imported robot's model is ever missing (stored_collision builds the rest).
        return self.keep_collision(robot_id, build_collision(self.imported(robot_id)))

    def stored_collision(self, robot_id: str) -> tuple[Any, str] | None:
        """The kept or stored collision model and its token; None when it must be built.
        ``KeyError`` if the robot is unknown."""
        model = self.get(robot_id)
        cached = self._collision.get(robot_id)
        if cached is not None and cached[0] is model:
            return cached[1], cached[2]
        from planning.collision import RobotCollisionModel

        robot = self.imported(robot_id)
        if robot is None:  # capsules: built in milliseconds, never stored
            return self._keep(robot_id, model, RobotCollisionModel.from_model(model))
        data = self._store.robot_file(robot_id, COLLISION_FILE) if self._store else None
        if data is None:
            return None

        try:
            cm = RobotCollisionModel.from_bytes(data, robot)
        except ValueError as exc:  # another format or other geometry: build it again
            log.warning("stored collision model of '%s' not used: %s", robot_id, exc)
            return None
        return self._keep(robot_id, model, cm)

    def robot_files(self, robot_id: str) -> dict[str, str] | None:
        """What a worker without the store needs to rebuild an imported robot and its
        collision model, as base64 text by name: ``description`` (its JSON), ``collision``
        (the built model) and ``mesh:<key>`` for each mesh of its collision geometry. None
        for built-in and model-JSON robots; ``CollisionNotReady`` while the model is still
        being built; ``KeyError`` if unknown."""
        import base64
        import json

        robot = self.imported(robot_id)
        if robot is None:
            return None
        entry = self.stored_collision(robot_id)
        if entry is None:
            raise CollisionNotReady(robot_id, f"the collision model of '{robot_id}' is "
                                    f"still being built (seconds): GET /robots/{robot_id}/"
                                    "collision waits for it, then submit again")
        from kinematics.urdf_import import mesh_to_bytes

        def b64(data: bytes) -> str:
            return base64.b64encode(data).decode("ascii")

        keys = sorted({g.mesh for link in robot.links for g in link.collision
                       if g.kind == "mesh"})
        # The worker checks collisions: the visual geometry (and its meshes) stays here.
        description = robot.to_dict()
        for link in description["links"]:
            link["visual"] = []
        description["meshes"] = keys
        out = {"description": b64(json.dumps(description).encode()),
               "collision": b64(entry[0].to_bytes())}
        for key in keys:
            out[f"mesh:{key}"] = b64(mesh_to_bytes(robot.meshes[key]))
        return out

    def keep_collision(self, robot_id: str, data: bytes) -> tuple[Any, str]:
        """Keep (and, for an imported robot, store) a collision model built by
        ``build_collision``; answers it with its token."""
        from planning.collision import RobotCollisionModel

        model = self.get(robot_id)
        robot = self.imported(robot_id)
        cm = RobotCollisionModel.from_bytes(data, robot or model)
        if robot is not None and self._store is not None:
            self._store.put_robot_file(robot_id, COLLISION_FILE, data)
        return self._keep(robot_id, model, cm)

    def _keep(self, robot_id: str, model: RobotModel, cm: Any) -> tuple[Any, str]:
        token = f"{robot_id}:{uuid.uuid4().hex}"
        with self._lock:
            self._collision = {**self._collision, robot_id: (model, cm, token)}
        return cm, token

    def remove(self, robot_id: str) -> None:
        """Delete a custom robot: ``ReadOnlyRobotError`` for a built-in, ``KeyError`` if
        unknown. A stored row that was skipped at start-up (corrupt) can be deleted too."""
        if robot_id in self._builtin:
            raise ReadOnlyRobotError(f"'{robot_id}' is a built-in robot and cannot be deleted")
        self._current()
        with self._lock:
            deleted = self._store.delete_robot(robot_id) if self._store is not None else False
            if robot_id not in self._custom and not deleted:
                raise KeyError(robot_id)
            self._custom = {k: v for k, v in self._custom.items() if k != robot_id}
            self._descriptions = {k: v for k, v in self._descriptions.items() if k != robot_id}
            self._imported = {k: v for k, v in self._imported.items() if k != robot_id}
            self._collision = {k: v for k, v in self._collision.items() if k != robot_id}
