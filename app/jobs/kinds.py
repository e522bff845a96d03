"""Job kinds: what a job can do, the parameters it takes, and the function that does it.

A kind's ``run(params, progress)`` is a module-level function, so a worker process (local
pool or Dask) can import and call it. ``params`` is the validated parameter dict, plus
anything the service resolved at submission (e.g. the robot model JSON under ``_model``, so
a worker needs no access to the service's registry). ``progress(fraction, message)``
reports 0..1; it raises ``JobCancelled`` when the job has been cancelled and the backend
can only stop it cooperatively.

Other modules add kinds with ``register``; the API validates params with the kind's
pydantic model before anything is queued.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from .caps import MAX_PARAMS_BYTES

__all__ = [
    "JobKind",
    "JobCancelled",
    "Progress",
    "KINDS",
    "MAX_SEED",
    "register",
    "get_kind",
    "run_kind",
    "KIND_MODULES",
    "load_kind_modules",
]

Progress = Callable[[float, str], None]

#: Largest random seed a job takes (a 32-bit generator seed).
MAX_SEED = 2**32 - 1


class JobCancelled(Exception):
    """Raised inside a job by ``progress`` once the job is cancelled."""


class Params(BaseModel):
    """Job parameters: unknown fields and NaN/inf are rejected (422 naming the field)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


@dataclass(frozen=True)
class JobKind:
    """A kind of job. ``needs_robot``: params name a robot whose model is attached;
    ``max_params_bytes``: the most JSON its params may take (413 above)."""

    name: str
    params: type[Params]
    run: Callable[[dict[str, Any], Progress], Any]
    description: str
    needs_robot: bool = False
    max_params_bytes: int = MAX_PARAMS_BYTES


KINDS: dict[str, JobKind] = {}

#: Modules that register job kinds; a worker imports them all before running a job.
KIND_MODULES: list[str] = [
    "app.jobs.kinds",
    "app.jobs.model_kinds",
    "app.jobs.path_kinds",
    "app.jobs.tracking_kinds",
    "app.jobs.drilling_kinds",
]


def load_kind_modules() -> None:
    """Import every module that registers kinds (in a fresh worker process)."""
    import importlib

    for name in KIND_MODULES:
        importlib.import_module(name)


def register(kind: JobKind) -> JobKind:
    """Make ``kind`` available to POST /jobs (idempotent for the same name and function)."""
    KINDS[kind.name] = kind
    return kind


def get_kind(name: str) -> JobKind:
    """The kind called ``name``; KeyError if unknown."""
    return KINDS[name]


def run_kind(name: str, params: dict[str, Any], progress: Progress) -> Any:
    """Run a job of kind ``name`` (in whatever process the backend chose)."""
    return KINDS[name].run(params, progress)


# ---- sleep: a diagnostic kind to check the pool itself ----------------------------------
class SleepParams(Params):
    seconds: float = Field(1.0, ge=0, le=3600, description="How long to run")
    steps: int = Field(10, ge=1, le=10_000, description="Progress reports on the way")
    outcome: Literal["succeed", "raise", "exit"] = Field(
        "succeed",
        description="'raise': end with an error; 'exit': the worker process dies abruptly "
        "(to check that only this job fails)",
    )


def run_sleep(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Sleep in steps, reporting progress; optionally fail in one of two ways at the end."""
    steps = params["steps"]
    for k in range(steps):
        time.sleep(params["seconds"] / steps)
        progress((k + 1) / steps, f"step {k + 1} of {steps} (pid {os.getpid()})")
    if params["outcome"] == "raise":
        raise RuntimeError("the sleep job was asked to fail")
    if params["outcome"] == "exit":
        os._exit(3)  # no cleanup, no message: as a crash would
    return {"slept": params["seconds"], "pid": os.getpid()}


register(JobKind("sleep", SleepParams, run_sleep,
                 "Sleep with progress; a diagnostic of the job pool"))


# ---- echo ------------------------------------------------------------------------------
class EchoParams(Params):
    value: Any = Field(None, description="Any JSON value, returned as the result (within the "
                       "limits of every job's params: size, nesting, finite numbers)")


def run_echo(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    progress(1.0, "done")
    return {"value": params["value"]}


register(JobKind("echo", EchoParams, run_echo, "Return the params' value"))


# ---- workspace -------------------------------------------------------------------------
class WorkspaceParams(Params):
    robot: str = Field(max_length=200, description="Robot id")
    samples: int = Field(30_000, ge=1, le=20_000_000, description="Monte Carlo samples")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    voxel: float | None = Field(None, gt=0, le=1e6, description="Voxel edge, mm")
    return_points: int = Field(20_000, ge=0, le=200_000)
    projections: bool = True


def run_workspace(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Monte Carlo workspace of a robot; the answer of POST /robots/{id}/workspace."""
    from kinematics.model import RobotModel
    from kinematics.workspace import sample_workspace, workspace_report

    model = RobotModel.from_dict(params["_model"])
    ws = sample_workspace(
        model, params["samples"], seed=params["seed"], voxel=params["voxel"],
        progress=lambda f: progress(0.95 * f, "sampling"), max_samples=math.inf,
    )
    out = {"robot": model.id} | workspace_report(ws, params["return_points"],
                                                 params["projections"])
    progress(1.0, "done")
    return out


register(JobKind("workspace", WorkspaceParams, run_workspace,
                 "Monte Carlo workspace (large N)", needs_robot=True))
