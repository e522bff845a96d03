"""The life of a robot's collision model in the service: built, kept, found again, dropped.

A built-in or model-JSON robot's collision model is a capsule per link, built in
milliseconds wherever it is needed. An imported robot's comes from its URDF collision
geometry (meshes: seconds): ``build_collision`` builds it in a compute worker, once per
robot at a time (``start_build``: a second request waits for the build in flight), and the
registry keeps it and stores it with the robot (``RobotRegistry.keep_collision``), so a
restart reads it back instead of building it again.

Every kept model has a token naming that build (``RobotRegistry.stored_collision``), and
every stored scene one naming that version of the scene (``scene_token``). A compute worker
keeps what it derived from a model or a scene (exact geometry, built on first use) by token
(``worker_cached``). Invalidation follows from the tokens: a robot that changes or is
deleted drops its registry entry (the next model gets a new token), and a scene stored again
has a new ``created`` stamp; a worker's entries of old tokens are never asked for again and
leave its small cache as new ones come.

HTTP stays in the routes: here an unknown stored scene is a ``KeyError`` and an inline scene
that does not build a ``FieldError`` whose ``loc`` is relative to the scene.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Mapping
from typing import Any

from starlette.concurrency import run_in_threadpool

from kinematics.errors import FieldError

__all__ = ["build_collision", "start_build", "collision_entry", "scene_token",
           "resolve_scene", "worker_cached", "WORKER_CACHE_SIZE", "INLINE_SCENE_KEYS"]

log = logging.getLogger(__name__)

#: Collision models and scenes one compute worker keeps, by token (a few of each).
WORKER_CACHE_SIZE = 8
#: Keys of an inline scene of a query (``{"objects": [...]}`` and/or ``{"moveit": {...}}``).
INLINE_SCENE_KEYS = ("objects", "moveit", "name")

_WORKER_CACHE: dict[str, Any] = {}


def build_collision(robot: Any) -> bytes:
    """Build the collision model of an imported robot (``ImportedRobot``) and answer it as
    bytes (``RobotCollisionModel.to_bytes``): the seconds of work a compute worker does."""
    from planning.collision import RobotCollisionModel

    return RobotCollisionModel.from_imported(robot).to_bytes()


def worker_cached(token: str | None, value: Any) -> Any:
    """In a compute worker: the value kept under ``token`` (what an earlier request derived
    from the same model or scene), else ``value``, now kept. ``token`` None: ``value``."""
    if token is None:
        return value
    kept = _WORKER_CACHE.get(token)
    if kept is not None:
        return kept
    while len(_WORKER_CACHE) >= WORKER_CACHE_SIZE:
        _WORKER_CACHE.pop(next(iter(_WORKER_CACHE)))
    _WORKER_CACHE[token] = value
    return value


async def _build(state: Any, robot_id: str) -> tuple[Any, str]:
    registry = state.registry
    robot = await run_in_threadpool(registry.imported, robot_id)
    data = await state.compute.run(True, build_collision, robot)
    return await run_in_threadpool(registry.keep_collision, robot_id, data)


def start_build(state: Any, robot_id: str) -> asyncio.Future:
    """The build of an imported robot's collision model in a compute worker (``state``: the
    application's state, with ``registry``, ``compute`` and ``collision_builds``): the one
    in flight, or a new one. Its result is kept and stored by the registry."""
    builds: dict[str, asyncio.Future] = state.collision_builds
    future = builds.get(robot_id)
    if future is None:
        future = asyncio.ensure_future(_build(state, robot_id))
        builds[robot_id] = future

        def done(f: asyncio.Future) -> None:
            builds.pop(robot_id, None)
            if not f.cancelled() and f.exception() is not None:
                log.warning("collision model of '%s' not built: %s", robot_id, f.exception())

        future.add_done_callback(done)
    return future


async def collision_entry(state: Any, registry: Any, robot_id: str) -> tuple[Any, str]:
    """The robot's collision model and its token: kept, stored, or built now in a compute
    worker (an imported robot's first query waits for it, seconds). ``KeyError`` if the
    robot is unknown."""
    entry = await run_in_threadpool(registry.stored_collision, robot_id)
    if entry is not None:
        return entry
    return await asyncio.shield(start_build(state, robot_id))


def scene_token(scenes: Any, scene_id: str) -> str:
    """The token of a stored scene as it is now (``KeyError`` if unknown): a scene stored
    again under the same id gets another."""
    return f"scene:{scene_id}:{scenes.describe(scene_id).get('created')}"


def resolve_scene(scenes: Any, scene: str | Mapping[str, Any] | None) -> tuple[Any, str | None]:
    """``(CollisionScene or None, token)`` of a query's ``scene``: a stored scene's id
    (``KeyError`` if unknown; its token), an inline scene (``FieldError`` at the object or
    key at fault, relative to the scene; no token) or None (no scene)."""
    if scene is None:
        return None, None
    if isinstance(scene, str):
        token = scene_token(scenes, scene)
        return scenes.get(scene), token
    unknown = sorted(set(scene) - set(INLINE_SCENE_KEYS))
    if unknown:
        raise FieldError((unknown[0],), "unknown field; an inline scene has objects and/or "
                         "moveit")
    return scenes.build(scene), None
