"""Tell the 3D viewer what to show."""

from __future__ import annotations

from fastapi import APIRouter, Request

from ..deps import RegistryDep
from ..errors import invalid, not_found, unavailable
from ..schemas import ViewerShowRequest

router = APIRouter(prefix="/viewer", tags=["viewer"])


@router.post("/show")
def viewer_show(request: Request, registry: RegistryDep, body: ViewerShowRequest) -> dict:
    """Show a robot in a configuration in the 3D viewer."""
    viewer = request.app.state.viewer
    if viewer is None:
        raise unavailable("viewer", "the 3D viewer is not running (started with --no-viewer)")
    if body.job is not None:
        raise not_found("job", body.job)
    if body.robot is None:
        raise invalid(["robot"], "name the robot to show")
    try:
        model = registry.get(body.robot)
    except KeyError:
        raise not_found("robot", body.robot) from None
    q = body.q if body.q is not None else model.mid_configuration().tolist()
    if len(q) != model.dof:
        raise invalid(["q"], f"expected {model.dof} joint values for robot '{model.id}', "
                      f"got {len(q)}")
    viewer.show_robot(model, q)
    return {"shown": viewer.current}
