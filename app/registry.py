"""Where the service finds robot models by id: the built-ins and the custom robots."""

from __future__ import annotations

import json
import logging
import threading

from kinematics.library import builtin_models
from kinematics.model import RobotModel
from kinematics.rigs import BUILTIN_RIG_IDS, Rig, builtin_rig

from .store import DuplicateError, Store, StoreError

__all__ = ["RobotRegistry", "RobotConflictError", "ReadOnlyRobotError"]

log = logging.getLogger(__name__)


class RobotConflictError(ValueError):
    """The id is a built-in's or already taken by a custom robot."""

    def __init__(self, robot_id: str, message: str):
        super().__init__(message)
        self.robot_id = robot_id


class ReadOnlyRobotError(ValueError):
    """Built-in robots cannot be changed or removed."""


class RobotRegistry:
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
        self._store = store
        self._lock = threading.Lock()
        self._generation = store.generation if store is not None else 0
        self._custom: dict[str, RobotModel] = self._load() if store is not None else {}

    def _load(self) -> dict[str, RobotModel]:
        """Every stored robot that still parses; a bad row is logged and skipped."""
        assert self._store is not None
        custom: dict[str, RobotModel] = {}
        for row in self._store.list_robots():
            try:
                model = RobotModel.from_dict(json.loads(row.model_json))
            except Exception as exc:  # any bad row (bad JSON, invalid model): keep starting
                log.error("skipping stored robot '%s': %s", row.id, exc)
                continue
            if model.id != row.id or row.id in self._builtin:
                log.error("skipping stored robot '%s': id clash (model id '%s')", row.id,
                          model.id)
                continue
            custom[row.id] = model
        return custom

    def _current(self) -> dict[str, RobotModel]:
        """The custom robots, loaded again first when the store has moved on to another file
        or works again after it could not be read (its ``generation`` changed)."""
        store = self._store
        if store is not None and store.generation != self._generation:
            with self._lock:
                generation = store.generation
                if generation != self._generation:
                    try:
                        self._custom = self._load()
                    except StoreError:  # still unusable: serve what we have, retry later
                        return self._custom
                    self._generation = generation
                    log.info("custom robots loaded again from the store (%d)",
                             len(self._custom))
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
        if model.id in self._builtin:
            raise RobotConflictError(model.id, f"'{model.id}' is a built-in robot id")
        # allow_nan=False: a model whose extra fields hold NaN could not be served as JSON.
        text = json.dumps(model.to_dict(), allow_nan=False)
        self._current()
        with self._lock:
            if model.id in self._custom:
                raise RobotConflictError(model.id, f"robot id '{model.id}' is taken")
            if self._store is not None:
                try:
                    self._store.put_robot(model.id, text)
                except DuplicateError:  # e.g. a stored row that no longer parses
                    raise RobotConflictError(
                        model.id, f"robot id '{model.id}' is taken in the store"
                    ) from None
            self._custom = {**self._custom, model.id: model}

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
