"""A toy job kind written by the recipe of docs/extending.md ("Adding a job kind"), with
every hook a kind may declare, for the tests of that recipe and of the hooks.

``toy_reach``: the tool positions of ``count`` configurations of a robot drawn from a seed,
and the farthest one from the base. Hooks: ``prepare`` fills a stored scene's name in as its
object count (what a worker could not look up); ``check`` refuses more configurations than
the robot has joints times 1000 (a check that needs the robot); ``needs_geometry`` and
``keep_latest`` are switched on so the tests can see their effect.

The test process registers the kind with ``register`` (and removes it after); a worker
process imports this module when it unpickles the kind's step function and registers it
here, as ``app.jobs.catalog`` would have at its start.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np
from pydantic import Field

from app.jobs.caps import ParamsLimitError
from app.jobs.kinds import (
    KINDS,
    MAX_SEED,
    XYZ,
    JobKind,
    Params,
    Progress,
    Result,
    Submission,
)

NAME = "toy_reach"


class ToyParams(Params):
    robot: str = Field(max_length=200, description="Robot id")
    count: int = Field(100, ge=1, le=100_000, description="Configurations drawn")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    scene: str | None = Field(None, description="A stored scene's id (filled in as "
                              "scene_objects when submitted)")
    scene_objects: int | None = Field(None, ge=0, description="Objects of that scene")


class ToyResult(Result):
    robot: str
    count: int
    farthest: XYZ = Field(description="The tool position farthest from the base axis, mm")
    reach: float = Field(description="Its distance from the base z axis, mm")
    scene_objects: int | None = None


def prepare_toy(params: dict[str, Any], submission: Submission) -> dict[str, Any]:
    """``prepare``: a stored scene's id is replaced by its object count."""
    scene = params.get("scene")
    if not isinstance(scene, str):
        return params
    try:
        stored = submission.scenes.describe(scene)
    except KeyError:
        raise ParamsLimitError(["params", "scene"], f"unknown scene '{scene}'", 404) from None
    return {**params, "scene": None, "scene_objects": len(stored["objects"])}


def check_toy(params: ToyParams, submission: Submission) -> None:
    """``check``: at most 1000 configurations per joint of the robot."""
    try:
        dof = submission.registry.get(params.robot).dof
    except KeyError:
        return  # the manager answers 404
    if params.count > 1000 * dof:
        raise ParamsLimitError(["params", "count"], f"at most {1000 * dof} configurations "
                               f"for a robot of {dof} joints")


def run_toy(params: ToyParams, progress: Progress) -> ToyResult:
    """The farthest tool position of ``count`` configurations drawn within the limits."""
    from kinematics.fk import fk

    model = params.robot_model()
    rng = np.random.default_rng(params.seed)
    q = rng.uniform(model.lower, model.upper, size=(params.count, model.dof))  # (N, dof)
    p = fk(model, q)[:, :3, 3]  # (N, 3) mm
    radial = np.hypot(p[:, 0], p[:, 1])
    k = int(np.argmax(radial))
    progress(1.0, "done")
    return ToyResult(robot=model.id, count=params.count, farthest=p[k].tolist(),
                     reach=float(radial[k]), scene_objects=params.scene_objects)


KIND = JobKind(NAME, ToyParams, ToyResult, run_toy, "The farthest reach of random "
               "configurations (a recipe's example)", needs_robot=True, prepare=prepare_toy,
               check=check_toy, needs_geometry=True, keep_latest=True)

if "pytest" not in sys.modules:  # a worker process: known as the catalog's kinds are
    KINDS.setdefault(NAME, KIND)
