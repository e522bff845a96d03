"""Collision queries: a robot's collision model, and configurations checked against a scene
and the robot itself. Building and keeping the models is ``app.collision_models``'s."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter, Request
from pydantic import ConfigDict, Field

from ...collision_models import worker_cached
from ...compute import ComputePool, encode_json
from ...fields import StrictModel, joint_input
from ...responses import FastJSONRoute
from ..common import collision_entry, joint_rows, resolve_scene
from ..deps import RegistryDep, RobotDep
from ..schemas import GLT_SWING, body_examples

router = APIRouter(prefix="/robots", tags=["collision"], route_class=FastJSONRoute)

#: Most configurations in one collision query (413 above). A colliding or nearly colliding
#: configuration costs up to a few milliseconds (the exact stage: FCL on the real shapes, and
#: exact distances of near misses on big meshes), so 1,000 keeps one request within seconds.
MAX_COLLISION_CONFIGS = 1_000
#: Above this many configurations a query runs in a compute worker.
HEAVY_COLLISION_CONFIGS = 100
#: Largest ``margin`` (mm).
MAX_MARGIN_MM = 100_000.0


class CollisionRequest(StrictModel):
    model_config = ConfigDict(
        extra="forbid", allow_inf_nan=False, populate_by_name=True,
        json_schema_extra=body_examples(
            {"q": [GLT_SWING["start"], [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]],
             "scene": GLT_SWING["scene"]},
            robot="glt_palletizer"))

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


def _answer(cm: Any, cm_token: str | None, scene: Any, scene_token: str | None, q, single,
            self_collision: bool, exact_distance: bool, margin: float) -> bytes:
    from planning.collision import check

    cm = worker_cached(cm_token, cm)
    scene = worker_cached(scene_token, scene) if scene is not None else None
    report = check(cm, q[0] if single else q, scene, self_collision=self_collision,
                   exact=True, exact_distance=exact_distance, margin=margin).to_dict()
    rows = [report] if single else [
        {k: report[k][i] for k in report} for i in range(len(report["collides"]))]
    results = [{"collides": r["collides"], "distance": r["distance"],
                "distance_exact": r["distance_exact"],
                "pairs": [{"link": a, "object": b} for a, b in r["pairs"]]} for r in rows]
    return encode_json({"results": results})


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
