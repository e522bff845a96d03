"""Helpers several route modules share: request values turned into what the library takes,
and the service's domain answers (``app.collision_models``) turned into HTTP errors. Routes
import from here, never from one another."""

from __future__ import annotations

from typing import Any

import numpy as np
from fastapi import Request

from kinematics.errors import FieldError
from kinematics.model import RobotModel

from .. import collision_models
from .deps import get_scenes
from .errors import http_error, invalid, not_found

__all__ = ["joint_rows", "resolve_scene", "collision_entry", "succeeded_job"]


def joint_rows(model: RobotModel, q: list, field: str = "q") -> tuple[np.ndarray, bool]:
    """Body ``q`` (one configuration or a list) -> ``(N, dof)`` array and whether it was one."""
    single = len(q) == 0 or not isinstance(q[0], list)
    rows = [q] if single else q
    try:  # one numpy pass when every row has the robot's length (the usual case)
        arr = np.asarray(rows, dtype=float)
    except ValueError:  # ragged rows: find the one at fault below
        arr = None
    if arr is not None and arr.ndim == 2 and arr.shape[1] == model.dof:
        return arr, single
    for k, row in enumerate(rows):
        if len(row) != model.dof:
            loc = [field] if single else [field, k]
            raise invalid(
                loc, f"expected {model.dof} joint values for robot '{model.id}', got {len(row)}"
            )
    # Finite and within ±MAX_JOINT_VALUE already: the request types check every value.
    return np.asarray(rows, dtype=float).reshape(len(rows), model.dof), single


def resolve_scene(request: Request, scene: str | dict | None, field: str = "scene"
                  ) -> tuple[Any, str | None]:
    """``(CollisionScene or None, token)`` of a body's ``scene``
    (``collision_models.resolve_scene``): 404 for an unknown stored scene, 422 naming the
    object at fault of an inline one."""
    try:
        return collision_models.resolve_scene(get_scenes(request), scene)
    except KeyError:
        raise not_found("scene", scene) from None
    except FieldError as exc:
        raise invalid([field, *exc.loc], exc.message) from None


async def collision_entry(request: Request, registry: Any, robot_id: str) -> tuple[Any, str]:
    """The robot's collision model and its token (``collision_models.collision_entry``)."""
    return await collision_models.collision_entry(request.app.state, registry, robot_id)


def succeeded_job(request: Request, job_id: str, what: str) -> tuple[Any, str]:
    """A succeeded job's record and its result's JSON text, for the routes that derive
    ``what`` (e.g. "a trajectory") from a result: 404 for an unknown job, 409 naming its
    status (and error) for one that has not succeeded."""
    from ..jobs.manager import JobStateError

    jobs = request.app.state.jobs
    try:
        job = jobs.get(job_id)
        if job.status != "succeeded":
            why = f" ({job.error})" if job.error else ""
            raise http_error(409, ["path", "job_id"], f"job {job_id} is {job.status}{why}: "
                             f"{what} exists once it has succeeded", "conflict")
        return job, jobs.result(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:  # ended otherwise between the two looks
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
