"""The life of a robot's collision model in the service: built, kept, found again, dropped.

A built-in or model-JSON robot's collision model is a capsule per link, built in
milliseconds wherever it is needed. An imported robot's comes from its URDF collision
geometry (meshes: seconds): ``build_collision`` builds it in a compute worker, once per
robot at a time (``start_build``: a second request waits for the build in flight), and the
registry keeps it and stores it with the robot (``RobotRegistry.keep_collision``), so a
restart reads it back instead of building it again.

Every kept model has a token naming that build (``RobotRegistry.stored_collision``), and
every stored scene one naming that version of the scene (``scene_token``), every inline
scene one naming its content (``inline_token``). A compute worker keeps what it derived from
a model or a scene (exact geometry, built on first use) by token (``worker_cached``).
Invalidation follows from the tokens: a robot that changes or is deleted drops its registry
entry (the next model gets a new token), a scene stored again has a new ``created`` stamp,
and an inline scene that differs has another digest; a worker's entries of old tokens are
never asked for again and leave its small cache (least recently used first) as new ones
come.

What a worker keeps is not sent to it again: once every worker has said it keeps a token's
value, ``run_kept`` hands them the token alone (and the value again only to a worker that
answers that it lacks it, ``Lacking``), so a request of a robot whose collision model
(megabytes for an imported robot) the workers hold pickles a few strings instead. A worker
also keeps what it prepared from a model and a scene for the compiled checks
(``worker_prepared``: a motion planner's ``MotionChecker``), keyed by the tokens and the
settings it was prepared with, and lends it to one request at a time.

HTTP stays in the routes: here an unknown stored scene is a ``KeyError`` and an inline scene
that does not build a ``FieldError`` whose ``loc`` is relative to the scene.
"""

from __future__ import annotations

import asyncio
import hashlib
import json
import logging
import os
from collections import OrderedDict
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from starlette.concurrency import run_in_threadpool

from kinematics.errors import FieldError

__all__ = ["build_collision", "start_build", "collision_entry", "scene_token",
           "resolve_scene", "inline_token", "worker_cached", "worker_kept", "worker_prepared",
           "run_kept", "Kept", "Lacking", "WORKER_CACHE_SIZE", "WORKER_PREPARED_SIZE",
           "INLINE_SCENES_SIZE", "INLINE_SCENE_KEYS"]

log = logging.getLogger(__name__)

#: Collision models and scenes one compute worker keeps, by token (a few of each).
WORKER_CACHE_SIZE = 8
#: Inline scenes the API process keeps built, by content (``resolve_scene``).
INLINE_SCENES_SIZE = 8
#: Keys of an inline scene of a query (``{"objects": [...]}`` and/or ``{"moveit": {...}}``).
INLINE_SCENE_KEYS = ("objects", "moveit", "name")

#: Prepared checkers one compute worker keeps (``worker_prepared``): a robot in a few scenes.
WORKER_PREPARED_SIZE = 4

_WORKER_CACHE: OrderedDict[str, Any] = OrderedDict()
_INLINE_SCENES: OrderedDict[str, Any] = OrderedDict()
_WORKER_PREPARED: OrderedDict[Hashable, Any] = OrderedDict()


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
    kept = worker_kept(token)
    if kept is not None:
        return kept
    while len(_WORKER_CACHE) >= WORKER_CACHE_SIZE:
        _WORKER_CACHE.popitem(last=False)
    _WORKER_CACHE[token] = value
    return value


def worker_kept(token: str) -> Any | None:
    """In a compute worker: the value kept under ``token``, None if it is not kept (never
    was, or left the cache). A value found becomes the most recently used."""
    kept = _WORKER_CACHE.get(token)
    if kept is not None:
        _WORKER_CACHE.move_to_end(token)
    return kept


@contextmanager
def worker_prepared(key: Hashable | None, build: Callable[[], Any],
                    reset: Callable[[Any], None]) -> Iterator[Any]:
    """In a compute worker: lend the object kept under ``key`` (built by ``build()`` when
    none is), then keep it again once the block ends without error, after ``reset(obj)``
    has undone what the block left set (a checker's deadline, its exact stage). ``key``
    None (made from something without a token: an inline scene naming a stored mesh): a
    fresh ``build()``, not kept.

    The object is out of the cache while lent, so no other request of the worker (a thread,
    a re-entrant call) uses it at the same time: that one builds its own. An object whose
    block raised is dropped (its state is unknown). At most ``WORKER_PREPARED_SIZE`` are
    kept, the least recently used leaving first."""
    prepared = _WORKER_PREPARED.pop(key, None) if key is not None else None
    if prepared is None:
        prepared = build()
    yield prepared
    if key is None:
        return
    reset(prepared)
    while len(_WORKER_PREPARED) >= WORKER_PREPARED_SIZE:
        _WORKER_PREPARED.popitem(last=False)
    _WORKER_PREPARED[key] = prepared


@dataclass(frozen=True)
class Kept:
    """Stands, in the arguments sent to a compute worker, for the value the worker keeps
    under ``token`` (``run_kept``)."""

    token: str


@dataclass(frozen=True)
class Lacking:
    """A compute worker's answer when it does not keep ``tokens``: the caller sends their
    values (``run_kept``)."""

    tokens: tuple[str, ...]


#: Tokens whose holders ``run_kept`` follows per pool, the least recently used forgotten
#: first.
HOLDERS_SIZE = 64


def _worker_id() -> int:
    """This compute worker's process id (the holder ``run_kept`` hears from)."""
    return os.getpid()


def _with_kept(fn: Callable[..., Any], values: Sequence[tuple[str | None, Any]],
               args: tuple) -> tuple[int, tuple[str, ...], Any]:
    """Run in a compute worker: ``fn(*values, *args)`` with every ``Kept`` value replaced
    by what the worker keeps under its token and every value sent with a token kept under
    it; ``Lacking`` (and ``fn`` not called) when a token is not kept. Answers ``(process
    id, the tokens it keeps now, the answer)``."""
    resolved, lacking, kept_now = [], [], []
    for token, value in values:
        if isinstance(value, Kept):
            kept = worker_kept(value.token)
            if kept is None:
                lacking.append(value.token)
            else:
                kept_now.append(value.token)
            resolved.append(kept)
        else:
            resolved.append(worker_cached(token, value))
            if token is not None:
                kept_now.append(token)
    pid = _worker_id()
    if lacking:
        return pid, tuple(kept_now), Lacking(tuple(lacking))
    return pid, tuple(kept_now), fn(*resolved, *args)


def _heard(holders: OrderedDict[str, set[int]], pid: int, kept: Sequence[str],
           lacking: Sequence[str], workers: int) -> None:
    """Note in ``holders`` (by token, the workers that keep its value) what worker ``pid``
    said it keeps and lacks. A worker lacking a token that as many workers as the pool has
    were said to keep (one was replaced, or dropped it): its holders are forgotten, so that
    the next requests send the value again."""
    for token in kept:
        holders.setdefault(token, set()).add(pid)
        holders.move_to_end(token)
    for token in lacking:
        known = holders.get(token)
        if known is not None:
            known.discard(pid)
            if len(known) >= workers:
                known.clear()
    while len(holders) > HOLDERS_SIZE:
        holders.popitem(last=False)


async def run_kept(pool: Any, fn: Callable[..., Any], values: Sequence[tuple[str | None, Any]],
                   *args: Any) -> Any:
    """``fn(*values, *args)`` in a compute worker of ``pool`` (``ComputePool``: its
    ``workers``, and its ``holders``, where this notes which worker keeps what), where
    ``values`` are ``(token, value)`` pairs (token None: a value sent every time, an inline
    scene). A value with a token (a collision model, a stored scene) is sent itself until
    every worker of the pool has said it keeps it (a worker keeps what it is sent by token,
    ``worker_cached``), then as its token alone: a model of megabytes is pickled once per
    worker, not per request. A worker that lacks a token after all (its cache let it go)
    answers ``Lacking`` and the call is made again with those values (at most twice; then
    with every value). ``fn`` must not answer a ``Lacking`` itself."""
    workers = max(1, int(pool.workers))
    holders: OrderedDict[str, set[int]] = pool.holders

    def sent(missing: set[str] | None) -> list[tuple[str | None, Any]]:
        out = []
        for token, value in values:
            by_token = token is not None and (
                token not in missing if missing is not None
                else len(holders.get(token, ())) >= workers)
            out.append((token, Kept(token) if by_token else value))
        return out

    missing: set[str] | None = None
    for attempt in range(3):
        call = sent(missing) if attempt < 2 else list(values)
        pid, kept, out = await pool.run(True, _with_kept, fn, call, args)
        lacking = out.tokens if isinstance(out, Lacking) else ()
        _heard(holders, pid, kept, lacking, workers)
        if not lacking:
            return out
        missing = set(lacking)
    raise RuntimeError("a compute worker lacked values it was sent")  # pragma: no cover


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
    robot is unknown.

    The answer is remembered for the robot's model as the registry serves it now
    (``state.collision_entries``): while that model stays the registry's, the next request
    finds it in the event loop instead of in the thread pool (a model changed, deleted or
    loaded again from the store is another object, and misses)."""
    entries: dict[str, tuple[Any, Any, str]] | None = getattr(state, "collision_entries", None)
    if entries is None:
        entries = state.collision_entries = {}
    try:
        model = registry.get(robot_id)
    except KeyError:
        model = None
    known = entries.get(robot_id)
    if known is not None and model is not None and known[0] is model:
        return known[1], known[2]
    entries.pop(robot_id, None)
    entry = await run_in_threadpool(registry.stored_collision, robot_id)
    if entry is None:
        entry = await asyncio.shield(start_build(state, robot_id))
    if model is not None:
        entries[robot_id] = (model, *entry)
    return entry


def scene_token(scenes: Any, scene_id: str) -> str:
    """The token of a stored scene as it is now (``KeyError`` if unknown): a scene stored
    again under the same id gets another."""
    return f"scene:{scene_id}:{scenes.describe(scene_id).get('created')}"


def inline_token(scene: Mapping[str, Any]) -> str | None:
    """The token of an inline scene: its content's digest, so that equal scenes sent again
    are the same scene to the API and to the workers. None for a scene that names a stored
    mesh (``"mesh": id``: the mesh's content is not in the body, and a mesh deleted and
    uploaded again under its id would be another) or that is not JSON."""
    try:
        text = json.dumps(scene, sort_keys=True, separators=(",", ":"), allow_nan=True)
    except (TypeError, ValueError):
        return None
    if '"mesh":' in text:
        return None
    return "inline:" + hashlib.sha256(text.encode()).hexdigest()


def resolve_scene(scenes: Any, scene: str | Mapping[str, Any] | None) -> tuple[Any, str | None]:
    """``(CollisionScene or None, token)`` of a query's ``scene``: a stored scene's id
    (``KeyError`` if unknown; its token), an inline scene (``FieldError`` at the object or
    key at fault, relative to the scene; the token of its content, ``inline_token``) or None
    (no scene). The last ``INLINE_SCENES_SIZE`` inline scenes built are kept by token: the
    same scene sent again is not parsed and checked again."""
    if scene is None:
        return None, None
    if isinstance(scene, str):
        token = scene_token(scenes, scene)
        return scenes.get(scene), token
    unknown = sorted(set(scene) - set(INLINE_SCENE_KEYS))
    if unknown:
        raise FieldError((unknown[0],), "unknown field; an inline scene has objects and/or "
                         "moveit")
    token = inline_token(scene)
    built = _INLINE_SCENES.get(token) if token is not None else None
    if built is not None:
        _INLINE_SCENES.move_to_end(token)
        return built, token
    built = scenes.build(scene)
    if token is not None:
        _INLINE_SCENES[token] = built
        while len(_INLINE_SCENES) > INLINE_SCENES_SIZE:
            _INLINE_SCENES.popitem(last=False)
    return built, token
