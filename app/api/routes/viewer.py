"""Tell the 3D viewer what to show: a robot (or rig) in a configuration, a finished job or the
answer of a motion request, and a stored scene.

The viewer is whichever ``app.viewer.ViewerPort`` the program that started the service handed
it (``python -m kinoplan``: ``web.viewer.Viewer``); this module never imports ``web``."""

from __future__ import annotations

from fastapi import APIRouter, Request

from kinematics.errors import FieldError

from ...responses import FastJSONRoute
from ...viewer import JobNotReady, ViewerPort
from ..deps import RegistryDep
from ..errors import conflict, http_error, invalid, unavailable
from ..schemas import ViewerShowRequest

router = APIRouter(prefix="/viewer", tags=["viewer"], route_class=FastJSONRoute)


@router.post("/show")
def viewer_show(request: Request, registry: RegistryDep, body: ViewerShowRequest) -> dict:
    """Show a robot in a configuration, a finished job's result (``problem``: one of a
    batch's) or a motion answer, and/or a stored scene (``"scene": null`` clears it), in the
    3D viewer."""
    viewer: ViewerPort | None = request.app.state.viewer
    if viewer is None:
        raise unavailable("viewer", "the 3D viewer is not running (started with --no-viewer)")
    has_scene = "scene" in body.model_fields_set
    if body.job is not None and (body.robot is not None or body.q is not None):
        raise invalid(["job"], "give either a job, or a robot (and q), not both")
    if body.motion is not None and (body.job is not None or body.robot is not None
                                    or body.q is not None):
        raise invalid(["motion"], "give a motion answer alone (and a scene), without a job, "
                      "robot or q")
    if body.problem is not None and body.job is None:
        raise invalid(["problem"], "a problem is one of a motion job's batch: give the job")
    if (body.job is None and body.robot is None and body.motion is None
            and (body.q is not None or not has_scene)):
        raise invalid(["robot"], "name the robot (or rig) to show, a job, a motion answer, "
                      "or a scene")
    if body.motion is not None:
        try:
            registry.get(body.motion.robot)
        except KeyError:
            raise http_error(404, ["body", "motion", "robot"], f"unknown robot "
                             f"'{body.motion.robot}'", "not_found") from None
    if body.scene is not None:  # checked first: an unknown scene changes nothing
        scenes = getattr(request.app.state, "scenes", None)
        try:
            if scenes is None:
                raise KeyError(body.scene)
            scenes.describe(body.scene)
        except KeyError:
            raise http_error(404, ["body", "scene"], f"unknown scene '{body.scene}'",
                             "not_found") from None
    if body.robot is not None:
        if body.robot not in registry.rigs:
            try:
                model = registry.get(body.robot)
            except KeyError:
                raise http_error(404, ["body", "robot"], f"unknown robot '{body.robot}'",
                                 "not_found") from None
            if body.q is not None and len(body.q) != model.dof:
                raise invalid(["q"], f"expected {model.dof} joint values for robot "
                              f"'{model.id}', got {len(body.q)}")
        elif body.q is not None:
            raise invalid(["q"], f"'{body.robot}' is a rig: it is shown at mid-limits, "
                          "give no q")
    shown: dict = {}
    if body.job is not None:
        try:
            shown = viewer.show_job(body.job, body.problem)
        except KeyError:
            raise http_error(404, ["body", "job"], f"unknown job '{body.job}'",
                             "not_found") from None
        except JobNotReady as exc:
            raise conflict(["job"], str(exc)) from None
        except FieldError as exc:  # a problem the job does not have
            raise invalid(list(exc.loc), exc.message) from None
        except ValueError as exc:
            raise invalid(["job"], str(exc)) from None
    elif body.motion is not None:
        try:
            shown = viewer.show_motion(body.motion)
        except ValueError as exc:  # joints of another robot, a path of the wrong width
            raise invalid(["motion"], str(exc)) from None
    elif body.robot is not None:
        try:
            shown = viewer.select(body.robot, body.q)
        except ValueError as exc:
            raise invalid(["q"], str(exc)) from None
    if has_scene:
        try:
            shown = {**shown, **viewer.show_scene(body.scene)}
        except KeyError:  # deleted meanwhile
            raise http_error(404, ["body", "scene"], f"unknown scene '{body.scene}'",
                             "not_found") from None
        except ValueError as exc:  # a stored scene that no longer parses
            raise invalid(["scene"], str(exc)) from None
    return {"shown": shown}
