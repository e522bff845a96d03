"""Robot models: list, read, add and delete custom robots, export URDF."""

from __future__ import annotations

import io
import math
import zipfile
from typing import Annotated, Any

from fastapi import APIRouter, Depends, File, Form, Path, Request, Response, UploadFile

from kinematics.cylinders import CylinderSet
from kinematics.ik import available_methods
from kinematics.model import MAX_DOF, RobotModel
from kinematics.urdf import imported_to_archive, imported_to_urdf, to_urdf

from ...collision_models import start_build
from ...compute import ComputePool
from ...registry import ReadOnlyRobotError, RobotConflictError
from ...responses import FastJSONRoute, loads_json
from ..deps import RegistryDep, RobotDep
from ..errors import conflict, forbidden, invalid, not_found, too_large
from ..schemas import JointSummary, RobotSummary

router = APIRouter(prefix="/robots", tags=["robots"], route_class=FastJSONRoute)
#: The routes that change state (guarded by the API key when one is set).
write_router = APIRouter(prefix="/robots", tags=["robots"], route_class=FastJSONRoute)

#: Largest robot model body accepted by POST /robots (413 above): a 32-joint model with
#: generous extra fields is a few KiB.
MAX_MODEL_BYTES = 256 * 1024
#: Deepest nesting of lists and objects in a model body (422 above; a model needs 4).
MAX_MODEL_DEPTH = 16

# The body is parsed by ``RobotModel.from_dict`` (the one validator of models), so its schema
# is written out here for the OpenAPI document only.
_NUMBER = {"type": "number"}
_POSE = {"type": "array", "items": {"type": "array", "items": _NUMBER, "minItems": 4,
                                    "maxItems": 4}, "minItems": 4, "maxItems": 4}
_VEC3 = {"type": "array", "items": _NUMBER, "minItems": 3, "maxItems": 3}
_MODEL_SCHEMA: dict[str, Any] = {
    "type": "object",
    "required": ["id", "joints"],
    "additionalProperties": True,
    "properties": {
        "id": {"type": "string", "pattern": "^[A-Za-z0-9_-]{1,64}$"},
        "name": {"type": "string"},
        "convention": {"enum": ["mdh", "sdh", "poe"], "default": "mdh"},
        "joints": {
            "type": "array", "minItems": 1, "maxItems": MAX_DOF,
            "items": {
                "type": "object", "additionalProperties": False,
                "required": ["lower", "upper"],
                "properties": {
                    "name": {"type": "string"},
                    "type": {"enum": ["revolute", "prismatic"], "default": "revolute"},
                    **{k: _NUMBER for k in ("a", "alpha", "d", "theta", "offset", "lower",
                                            "upper", "velocity")},
                    "axis": _VEC3, "point": _VEC3,
                },
            },
        },
        "base": _POSE, "tool": _POSE, "home": _POSE,
    },
    "example": {
        "id": "my_arm", "name": "My arm", "convention": "mdh",
        "joints": [
            {"name": "j1", "type": "revolute", "a": 0, "alpha": 0, "d": 0, "offset": 0,
             "lower": -3.1, "upper": 3.1, "velocity": 1.0},
            {"name": "j2", "type": "prismatic", "a": 150, "alpha": -1.5708, "theta": 0,
             "offset": 0, "lower": 0, "upper": 800},
        ],
    },
}
_MODEL_BODY_DOC = {
    "requestBody": {
        "required": True,
        "description": f"Robot model JSON (see GET /robots/{{robot_id}}); at most "
        f"{MAX_MODEL_BYTES // 1024} KiB",
        "content": {"application/json": {"schema": _MODEL_SCHEMA}},
    }
}

def _check_values(data: Any) -> None:
    """422 naming the first non-finite number (JSON ``NaN``/``Infinity`` parse as floats) or
    the first value nested deeper than ``MAX_MODEL_DEPTH``."""
    stack: list[tuple[Any, list[str | int]]] = [(data, [])]
    while stack:
        value, loc = stack.pop()
        if isinstance(value, float) and not math.isfinite(value):
            raise invalid(loc, "must be a finite number")
        if isinstance(value, dict | list):
            if len(loc) >= MAX_MODEL_DEPTH:
                raise invalid(loc, f"nested deeper than {MAX_MODEL_DEPTH} levels")
            items = value.items() if isinstance(value, dict) else enumerate(value)
            stack.extend((v, [*loc, k]) for k, v in reversed(list(items)))


async def model_body(request: Request) -> Any:
    """The request body as JSON, read up to ``MAX_MODEL_BYTES`` (413 beyond, unread)."""
    cap = f"a robot model is at most {MAX_MODEL_BYTES} bytes"
    declared = request.headers.get("content-length", "")
    if declared.isdigit() and int(declared) > MAX_MODEL_BYTES:
        raise too_large([], f"{cap}, got {declared}")
    chunks: list[bytes] = []
    size = 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > MAX_MODEL_BYTES:
            raise too_large([], cap)
        chunks.append(chunk)
    try:
        return loads_json(b"".join(chunks))
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, UnicodeDecodeError
        raise invalid([], f"body is not valid JSON: {exc}") from None


ModelBody = Annotated[Any, Depends(model_body)]
RobotIdPath = Annotated[str, Path(description="Robot id, e.g. 'glt_palletizer'")]


@router.get("", response_model=list[RobotSummary])
def list_robots(registry: RegistryDep) -> list[RobotSummary]:
    """Every robot the service knows, built-in and custom."""
    return [
        RobotSummary(
            id=m.id, name=m.name, dof=m.dof, builtin=registry.is_builtin(m.id),
            convention=m.convention,
            joints=[
                JointSummary(name=j.name, type=j.type, lower=j.lower, upper=j.upper)
                for j in m.joints
            ],
            ik_methods=available_methods(m),
        )
        for m in registry.all()
    ]


@write_router.post(
    "", status_code=201, openapi_extra=_MODEL_BODY_DOC,
    responses={409: {"description": "Id taken or a built-in's"},
               413: {"description": "Body too large"}, 422: {"description": "Invalid model"}},
)
def create_robot(registry: RegistryDep, data: ModelBody) -> dict[str, Any]:
    """Add a custom robot (stored); answers its model JSON."""
    if not isinstance(data, dict):
        raise invalid([], "a robot model must be a JSON object")
    _check_values(data)
    # ModelError and CylinderError are FieldErrors naming the field (``joints[2].lower`` at
    # ["body", "joints", 2, "lower"]): the service answers them 422 there.
    model = RobotModel.from_dict(data)
    if {"cylinders", "pump_flow", "pump_cylinders"} & set(model.extras):
        # Bad cylinder data is the model's fault: 422 now, not NaN in every later answer
        # through a linkage that cannot close somewhere in its joint's range. (An import from
        # URDF cannot carry cylinders: this is the one way in for them.)
        CylinderSet.from_model(model).check_mechanisms()
    try:
        registry.add(model)
    except RobotConflictError as exc:
        raise conflict(["id"], str(exc)) from None
    return model.to_dict()


@router.get("/{robot_id}")
def get_robot_model(robot: RobotDep) -> dict[str, Any]:
    """The robot's model JSON (the schema POST /robots takes)."""
    return robot.to_dict()


@write_router.delete(
    "/{robot_id}", status_code=204, response_class=Response,
    responses={403: {"description": "Built-in robot"}, 404: {"description": "Unknown robot"}},
)
def delete_robot(registry: RegistryDep, robot_id: RobotIdPath) -> Response:
    """Delete a custom robot (built-ins are read-only)."""
    try:
        registry.remove(robot_id)
    except ReadOnlyRobotError as exc:
        raise forbidden("robot", robot_id, str(exc)) from None
    except KeyError:
        raise not_found("robot", robot_id) from None
    return Response(status_code=204)


@router.get(
    "/{robot_id}/urdf", response_class=Response,
    responses={200: {"description": "URDF XML (metres, rad)",
                     "content": {"application/xml": {}}}},
)
def get_robot_urdf(robot: RobotDep, registry: RegistryDep) -> Response:
    """The robot as URDF XML (lengths in metres; joint values as in the API). An imported
    robot is exported with all its links and geometry, its meshes referenced as
    ``meshes/<key>.stl`` (``GET /robots/{robot_id}/meshes/{key}``)."""
    imported = registry.imported(robot.id)
    if imported is not None:
        return Response(imported_to_urdf(imported), media_type="application/xml")
    return Response(to_urdf(robot), media_type="application/xml")


@router.get(
    "/{robot_id}/archive", response_class=Response,
    responses={200: {"description": "Zip of the URDF and its meshes (binary STL, metres)",
                     "content": {"application/zip": {}}}},
)
def get_robot_archive(robot: RobotDep, registry: RegistryDep) -> Response:
    """The robot as a zip: ``<id>.urdf`` and, for an imported robot, its meshes under
    ``meshes/``; it imports again as it is (``POST /robots/import``)."""
    imported = registry.imported(robot.id)
    if imported is not None:
        data = imported_to_archive(imported)
    else:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr(f"{robot.id}.urdf", to_urdf(robot))
        data = buf.getvalue()
    return Response(data, media_type="application/zip", headers={
        "content-disposition": f'attachment; filename="{robot.id}.zip"'})


# ---- import from URDF ---------------------------------------------------------------------

def _import_worker(data: bytes, filename: str, options: dict[str, Any]
                   ) -> tuple[Any, dict[str, bytes]]:
    """Run in a compute worker: parse the upload, load its meshes, build the robot; answer
    it with its mesh files encoded for the store."""
    from kinematics.urdf_import import import_robot, mesh_to_bytes

    robot = import_robot(data, filename, **options)
    return robot, {key: mesh_to_bytes(mesh) for key, mesh in robot.meshes.items()}


def _fixed_joints(text: str | None) -> dict[str, float] | None:
    if text is None or not text.strip():
        return None
    try:
        value = loads_json(text)
    except ValueError as exc:
        raise invalid(["fixed_joints"], f"must be a JSON object name -> value: {exc}") from None
    if not isinstance(value, dict) or len(value) > MAX_DOF * 8:
        raise invalid(["fixed_joints"], "must be a JSON object of at most "
                      f"{MAX_DOF * 8} joint names -> values")
    for name, v in value.items():
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise invalid(["fixed_joints", name], "must be a finite number")
    return {str(k): float(v) for k, v in value.items()}


@write_router.post(
    "/import", status_code=201,
    responses={409: {"description": "Id taken or a built-in's"},
               413: {"description": "Upload too large"},
               422: {"description": "Invalid URDF, archive, mesh or option; the field and "
                                    "element at fault are named"}},
)
async def import_robot_route(
    request: Request,
    registry: RegistryDep,
    file: Annotated[UploadFile, File(description="A .urdf file, or a .zip / .tar.gz holding "
                                                 "the URDF and its meshes")],
    id: Annotated[str, Form(pattern=r"^[A-Za-z0-9_-]{1,64}$",
                            description="Id of the new robot")],
    name: Annotated[str | None, Form(max_length=200)] = None,
    urdf: Annotated[str | None, Form(max_length=1000, description="Which URDF of the "
                                     "archive, when it holds several")] = None,
    base_link: Annotated[str | None, Form(max_length=200, description="Default: the URDF "
                                          "root (or the SRDF group's chain base)")] = None,
    tip_link: Annotated[str | None, Form(max_length=200, description="Default: the end of "
                                         "the only movable chain")] = None,
    srdf: Annotated[UploadFile | None, File(description="SRDF: disabled collision pairs "
                                            "and groups")] = None,
    group: Annotated[str | None, Form(max_length=200, description="SRDF group whose chain "
                                      "gives base and tip")] = None,
    fixed_joints: Annotated[str | None, Form(max_length=64 * 1024, description="JSON object: "
                                             "joint name -> value for movable joints off the "
                                             "chain (default 0)")] = None,
) -> dict[str, Any]:
    """Import a robot from URDF (with its meshes): stored, served like any custom robot, with
    its links, collision geometry and meshes. Answers the stored model (as
    ``GET /robots/{robot_id}``)."""
    if registry.is_builtin(id) or id in registry.ids():
        raise conflict(["id"], f"robot id '{id}' is taken")
    options: dict[str, Any] = {
        "robot_id": id, "name": name, "urdf": urdf, "base_link": base_link,
        "tip_link": tip_link, "group": group, "fixed_joints": _fixed_joints(fixed_joints),
        "srdf": await srdf.read() if srdf is not None else None,
    }
    data = await file.read()
    pool: ComputePool = request.app.state.compute
    robot, files = await pool.run(True, _import_worker, data, file.filename or "robot.urdf",
                                  options)
    try:
        registry.add_imported(robot, files)
    except RobotConflictError as exc:
        raise conflict(["id"], str(exc)) from None
    # Its collision model is built now, in a compute worker, and stored: the first collision
    # query finds it ready (or waits for this build). The answer says so, and how to wait.
    answer = robot.model.to_dict()
    if not any(link.collision for link in robot.links):
        answer["collision_model"] = {
            "state": "none", "message": "no <collision> geometry: nothing is checked for "
            "collision (motion plans ignore the robot's own shape)"}
        return answer
    wait = f"GET /robots/{id}/collision waits for it and answers when it is ready"
    if request.app.state.settings.prebuild_collision:
        start_build(request.app.state, id)
        answer["collision_model"] = {
            "state": "building", "message": "being built from the collision geometry in a "
            f"worker (seconds; collision queries and motion wait for it, motion jobs answer "
            f"409 until then): {wait}"}
    else:
        answer["collision_model"] = {
            "state": "on_first_use", "message": f"built at the first collision query: {wait}"}
    return answer
