"""Robot models: list, read, add and delete custom robots, export URDF."""

from __future__ import annotations

import json
import math
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Request, Response

from kinematics.cylinders import CylinderSet
from kinematics.ik import available_methods
from kinematics.model import MAX_DOF, RobotModel
from kinematics.urdf import to_urdf

from ...registry import ReadOnlyRobotError, RobotConflictError
from ..deps import RegistryDep, RobotDep
from ..errors import conflict, forbidden, invalid, not_found, too_large
from ..schemas import JointSummary, RobotSummary

router = APIRouter(prefix="/robots", tags=["robots"])
#: The routes that change state (guarded by the API key when one is set).
write_router = APIRouter(prefix="/robots", tags=["robots"])

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
        return json.loads(b"".join(chunks))
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
    if "cylinders" in model.extras:
        CylinderSet.from_model(model)  # bad cylinder data is the model's fault: 422 now
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
def get_robot_urdf(robot: RobotDep) -> Response:
    """The robot as URDF XML (lengths in metres; joint values as in the API)."""
    return Response(to_urdf(robot), media_type="application/xml")
