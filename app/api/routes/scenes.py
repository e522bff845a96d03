"""Scenes (a site's geometry, stored) and the meshes they use."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import APIRouter, Depends, File, Form, Path, Query, Request, Response, UploadFile

from ...jobs.caps import ParamsLimitError, check_params
from ...responses import FastJSONRoute, loads_json
from ...scenes import MeshInUseError, SceneConflictError
from ..deps import ScenesDep
from ..errors import conflict, http_error, invalid, not_found, too_large

router = APIRouter(tags=["scenes"], route_class=FastJSONRoute)
#: The routes that change state (guarded by the API key when one is set).
write_router = APIRouter(tags=["scenes"], route_class=FastJSONRoute)

#: Largest scene body (413 above): a scanned cloud of 200,000 points, or MoveIt meshes inline.
MAX_SCENE_BYTES = 24 * 1024 * 1024
#: Deepest nesting of a scene body (a MoveIt scene needs 8).
MAX_SCENE_DEPTH = 16
#: Largest uploaded mesh file.
MAX_MESH_FILE_BYTES = 32 * 1024 * 1024

IdPath = Annotated[str, Path(pattern=r"^[A-Za-z0-9_-]{1,64}$")]


async def json_body(request: Request, cap: int, depth: int) -> Any:
    """The request body as JSON, read up to ``cap`` bytes (413 beyond), checked for depth and
    non-finite numbers (422 naming where)."""
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > cap:
        raise too_large([], f"a body here is at most {cap} bytes, got {declared}")
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > cap:
            raise too_large([], f"a body here is at most {cap} bytes")
        chunks.append(chunk)
    try:
        data = loads_json(b"".join(chunks))
    except (ValueError, RecursionError) as exc:
        raise invalid([], f"body is not valid JSON: {exc}") from None
    try:
        check_params(data, max_bytes=cap, max_depth=depth)
    except ParamsLimitError as exc:
        loc = exc.loc[1:]  # check_params names the root "params"; here it is the body
        raise http_error(exc.status, ["body", *loc], exc.message,
                         "too_large" if exc.status == 413 else "value_error") from None
    return data


async def scene_body(request: Request) -> Any:
    return await json_body(request, MAX_SCENE_BYTES, MAX_SCENE_DEPTH)


_SCENE_DOC = {
    "requestBody": {
        "required": True,
        "description": "A scene: `id`, optional `name`, and `objects` (mm, 4x4 poses) and/or "
                       "`moveit` (a MoveIt PlanningScene as its YAML parses, metres)",
        "content": {"application/json": {"schema": {
            "type": "object", "required": ["id"],
            "properties": {
                "id": {"type": "string", "pattern": "^[A-Za-z0-9_-]{1,64}$"},
                "name": {"type": "string", "maxLength": 200},
                "objects": {"type": "array", "items": {"type": "object"}},
                "moveit": {"type": "object"},
            },
            "example": {"id": "cell", "objects": [
                {"type": "box", "id": "table", "size": [1200, 800, 40],
                 "pose": [[1, 0, 0, 600], [0, 1, 0, 0], [0, 0, 1, 380], [0, 0, 0, 1]]},
                {"type": "cylinder", "id": "post", "radius": 60, "height": 1500,
                 "pose": [[1, 0, 0, -400], [0, 1, 0, 500], [0, 0, 1, 750], [0, 0, 0, 1]]},
            ]},
        }}},
    }
}


def _summary(entry: dict) -> dict:
    return {"id": entry["id"], "name": entry.get("name"), "objects": len(entry["objects"]),
            "created": entry.get("created")}


@router.get("/scenes")
def list_scenes(scenes: ScenesDep) -> list[dict]:
    """Every stored scene: id, name, object count."""
    return [_summary(scenes.describe(sid)) for sid in scenes.ids()]


@write_router.post(
    "/scenes", status_code=201, openapi_extra=_SCENE_DOC,
    responses={409: {"description": "Id taken"}, 413: {"description": "Body too large"},
               422: {"description": "Invalid scene; the object and field at fault named"}},
)
def create_scene(scenes: ScenesDep, data: Annotated[Any, Depends(scene_body)]) -> dict:
    """Store a scene given as objects and/or a MoveIt planning scene; answers it as stored
    (objects in mm)."""
    if not isinstance(data, dict):
        raise invalid([], "a scene must be a JSON object")
    unknown = sorted(set(data) - {"id", "name", "objects", "moveit"})
    if unknown:
        raise invalid([unknown[0]], "unknown field; a scene has id, name, objects, moveit")
    scene_id = data.get("id")
    if not isinstance(scene_id, str) or not scene_id or len(scene_id) > 64 or \
            not all(c.isascii() and (c.isalnum() or c in "_-") for c in scene_id):
        raise invalid(["id"], "give the scene an id: 1 to 64 ASCII letters, digits, '_', '-'")
    name = data.get("name")
    if name is not None and (not isinstance(name, str) or len(name) > 200
                             or not name.isprintable()):
        raise invalid(["name"], "a name is printable text of at most 200 characters")
    if "objects" not in data and "moveit" not in data:
        raise invalid(["objects"], "give the scene's objects, a MoveIt scene (moveit), or both")
    try:
        return scenes.add(scene_id, data)
    except SceneConflictError as exc:
        raise conflict(["id"], str(exc)) from None


@router.get("/scenes/{scene_id}")
def get_scene(scenes: ScenesDep, scene_id: IdPath,
              format: Annotated[str, Query(pattern="^(objects|moveit)$")] = "objects"
              ) -> dict:
    """The stored scene; ``?format=moveit`` answers it as a MoveIt PlanningScene (metres)."""
    try:
        entry = scenes.describe(scene_id)
    except KeyError:
        raise not_found("scene", scene_id) from None
    if format == "moveit":
        from planning.collision import scene_to_moveit

        return scene_to_moveit(scenes.get(scene_id), name=entry.get("name") or scene_id)
    return entry


@write_router.delete("/scenes/{scene_id}", status_code=204, response_class=Response,
                     responses={404: {"description": "Unknown scene"}})
def delete_scene(scenes: ScenesDep, scene_id: IdPath) -> Response:
    """Delete a scene."""
    try:
        scenes.remove(scene_id)
    except KeyError:
        raise not_found("scene", scene_id) from None
    return Response(status_code=204)


# ---- meshes -----------------------------------------------------------------------------

@router.get("/meshes")
def list_meshes(scenes: ScenesDep) -> list[dict]:
    """Every uploaded mesh: id, file name, vertex and triangle counts, bounds (mm)."""
    return [scenes.mesh_info(mid) for mid in scenes.mesh_ids()]


@router.get("/meshes/{mesh_id}")
def get_mesh(scenes: ScenesDep, mesh_id: IdPath) -> dict:
    """What is stored of a mesh (not its triangles)."""
    try:
        return scenes.mesh_info(mesh_id)
    except KeyError:
        raise not_found("mesh", mesh_id) from None


@write_router.post(
    "/meshes", status_code=201,
    responses={409: {"description": "Id taken"}, 413: {"description": "File too large"},
               422: {"description": "Not a mesh, or too many triangles"}},
)
async def upload_mesh(
    request: Request,
    scenes: ScenesDep,
    file: Annotated[UploadFile, File(description="An STL, OBJ or PLY file")],
    id: Annotated[str, Form(pattern=r"^[A-Za-z0-9_-]{1,64}$", description="Id of the mesh")],
    scale: Annotated[float, Form(gt=0, le=1e6, description="Factor to mm: 1 for a file in "
                                 "mm, 1000 for one in metres")] = 1.0,
) -> dict:
    """Upload a mesh for scenes to use (``{"type": "mesh", "mesh": id}``)."""
    from planning.collision import load_mesh_file

    if id in scenes.mesh_ids():
        raise conflict(["id"], f"mesh id '{id}' is taken")
    data = await file.read(MAX_MESH_FILE_BYTES + 1)
    if len(data) > MAX_MESH_FILE_BYTES:
        raise too_large(["file"], f"a mesh file is at most {MAX_MESH_FILE_BYTES} bytes")
    filename = file.filename or "mesh.stl"
    vertices, faces = await request.app.state.compute.run(
        True, load_mesh_file, data, filename)
    try:
        return scenes.add_mesh(id, vertices * scale, faces, filename)
    except SceneConflictError as exc:
        raise conflict(["id"], str(exc)) from None


@write_router.delete("/meshes/{mesh_id}", status_code=204, response_class=Response,
                     responses={404: {"description": "Unknown mesh"},
                                409: {"description": "A scene uses the mesh"}})
def delete_mesh(scenes: ScenesDep, mesh_id: IdPath) -> Response:
    """Delete a mesh no scene uses."""
    try:
        scenes.remove_mesh(mesh_id)
    except KeyError:
        raise not_found("mesh", mesh_id) from None
    except MeshInUseError as exc:
        raise http_error(409, ["path", "mesh_id"], str(exc), "conflict") from None
    return Response(status_code=204)
