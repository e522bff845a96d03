"""Collision queries: a robot's collision model, and configurations checked against a scene
and the robot itself."""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from fastapi import APIRouter, Request
from pydantic import ConfigDict, Field
from starlette.concurrency import run_in_threadpool

from ...compute import ComputePool, encode_json
from ...fields import StrictModel, joint_input
from ...registry import build_collision
from ...responses import FastJSONRoute
from ..deps import RegistryDep, RobotDep
from ..errors import invalid, not_found
from .kinematics import joint_rows
from .scenes import get_scenes

router = APIRouter(prefix="/robots", tags=["collision"], route_class=FastJSONRoute)
log = logging.getLogger(__name__)

#: Most configurations in one collision query (413 above). A colliding or nearly colliding
#: configuration costs up to a few milliseconds (the exact stage: FCL on the real shapes, and
#: exact distances of near misses on big meshes), so 1,000 keeps one request within seconds.
MAX_COLLISION_CONFIGS = 1_000
#: Above this many configurations a query runs in a compute worker.
HEAVY_COLLISION_CONFIGS = 100
#: Largest ``margin`` (mm).
MAX_MARGIN_MM = 100_000.0


class CollisionRequest(StrictModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, populate_by_name=True)

    q: joint_input(MAX_COLLISION_CONFIGS) = Field(
        description="One configuration or a list of them (rad or mm per joint; at most "
                    f"{MAX_COLLISION_CONFIGS})")
    scene: str | dict[str, Any] | None = Field(
        None, description="A stored scene's id, an inline scene ({\"objects\": [...]} and/or "
                          "{\"moveit\": {...}}), or none (self-collision only)")
    self_collision: bool = Field(True, alias="self",
                                 description="Check the robot against itself too")
    exact_distance: bool = Field(
        False, description="Measure the exact distance of free configurations (slower); "
                           "otherwise a free configuration's distance is the sphere models' "
                           "(a lower bound of the true clearance)")
    margin: float = Field(0.0, ge=0.0, le=MAX_MARGIN_MM,
                          description="mm: closer than this counts as a collision")


#: Collision models and scenes a compute worker has built, by token (their exact geometry is
#: built on first use and kept; a few of each).
_WORKER_CACHE: dict[str, Any] = {}
_WORKER_CACHE_SIZE = 8


def _cached(token: str | None, value: Any) -> Any:
    if token is None:
        return value
    kept = _WORKER_CACHE.get(token)
    if kept is not None:
        return kept
    while len(_WORKER_CACHE) >= _WORKER_CACHE_SIZE:
        _WORKER_CACHE.pop(next(iter(_WORKER_CACHE)))
    _WORKER_CACHE[token] = value
    return value


def _answer(cm: Any, cm_token: str | None, scene: Any, scene_token: str | None, q, single,
            self_collision: bool, exact_distance: bool, margin: float) -> bytes:
    from planning.collision import check

    cm = _cached(cm_token, cm)
    scene = _cached(scene_token, scene) if scene is not None else None
    report = check(cm, q[0] if single else q, scene, self_collision=self_collision,
                   exact=True, exact_distance=exact_distance, margin=margin).to_dict()
    rows = [report] if single else [
        {k: report[k][i] for k in report} for i in range(len(report["collides"]))]
    results = [{"collides": r["collides"], "distance": r["distance"],
                "distance_exact": r["distance_exact"],
                "pairs": [{"link": a, "object": b} for a, b in r["pairs"]]} for r in rows]
    return encode_json({"results": results})


def resolve_scene(request: Request, scene: str | dict | None, field: str = "scene"
                  ) -> tuple[Any, str | None]:
    """``(CollisionScene or None, token)`` for a stored scene id (404 when unknown) or an
    inline scene (422 naming the object at fault)."""
    if scene is None:
        return None, None
    scenes = get_scenes(request)
    if isinstance(scene, str):
        try:
            entry = scenes.describe(scene)
            return scenes.get(scene), f"scene:{scene}:{entry.get('created')}"
        except KeyError:
            raise not_found("scene", scene) from None
    unknown = sorted(set(scene) - {"objects", "moveit", "name"})
    if unknown:
        raise invalid([field, unknown[0]], "unknown field; an inline scene has objects "
                      "and/or moveit")
    from kinematics.errors import FieldError

    try:
        return scenes.build(scene), None
    except FieldError as exc:
        raise invalid([field, *exc.loc], exc.message) from None


async def _build(app: Any, robot_id: str) -> tuple[Any, str]:
    registry = app.state.registry
    robot = await run_in_threadpool(registry.imported, robot_id)
    data = await app.state.compute.run(True, build_collision, robot)
    return await run_in_threadpool(registry.keep_collision, robot_id, data)


def start_collision_build(app: Any, robot_id: str) -> asyncio.Future:
    """The build of an imported robot's collision model, in a compute worker: the one in
    flight, or a new one. Its result is kept and stored by the registry."""
    builds: dict[str, asyncio.Future] = app.state.collision_builds
    future = builds.get(robot_id)
    if future is None:
        future = asyncio.ensure_future(_build(app, robot_id))
        builds[robot_id] = future

        def done(f: asyncio.Future) -> None:
            builds.pop(robot_id, None)
            if not f.cancelled() and f.exception() is not None:
                log.warning("collision model of '%s' not built: %s", robot_id, f.exception())

        future.add_done_callback(done)
    return future


async def collision_entry(request: Request, registry: Any, robot_id: str) -> tuple[Any, str]:
    """The robot's collision model and its token: kept, stored, or built now in a compute
    worker (an imported robot's first query waits for it, seconds)."""
    entry = await run_in_threadpool(registry.stored_collision, robot_id)
    if entry is not None:
        return entry
    return await asyncio.shield(start_collision_build(request.app, robot_id))


@router.get("/{robot_id}/collision")
async def collision_model(robot: RobotDep, registry: RegistryDep, request: Request) -> dict:
    """The robot's collision model: per link its shapes, how many spheres approximate them
    (and their centres and radii), and the link pairs checked for self-collision."""
    cm, _ = await collision_entry(request, registry, robot.id)
    return cm.describe()


@router.post("/{robot_id}/collision")
async def check_collision(robot: RobotDep, registry: RegistryDep, body: CollisionRequest,
                          request: Request) -> Any:
    """Check configurations against a scene and the robot itself: per configuration whether
    it collides, the distance (mm; at most 0 in contact) and the colliding pairs (or the
    closest pair when free)."""
    from fastapi import Response

    q, single = joint_rows(robot, body.q)
    scene, scene_token = resolve_scene(request, body.scene)
    cm, cm_token = await collision_entry(request, registry, robot.id)
    heavy = len(q) > HEAVY_COLLISION_CONFIGS
    pool: ComputePool = request.app.state.compute
    data = await pool.run(heavy, _answer, cm, cm_token if heavy else None, scene,
                          scene_token if heavy else None, q, single, body.self_collision,
                          body.exact_distance, body.margin)
    return Response(data, media_type="application/json")
