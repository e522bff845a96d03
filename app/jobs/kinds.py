"""Job kinds: what a job can do, the parameters it takes, the result it gives, and the function
that does it.

A kind declares, side by side, its ``Params`` model (what ``POST /jobs`` accepts), its
``Result`` model (the JSON of ``GET /jobs/{id}/result``) and its runner
``run(params: Params, progress) -> Result``, a module-level function, so a worker process
(local pool or Dask) can import and call it. ``progress(fraction, message)`` reports 0..1; it
raises ``JobCancelled`` when the job has been cancelled and the backend can only stop it
cooperatively. Optional hook: ``plot(params, result, robot) -> PNG bytes`` (``GET
/jobs/{id}/plot``; ``robot`` is the job's robot model as the service knows it now, or None).
Submission hooks (``JobKind``: ``prepare``, ``check``, ``needs_geometry``, ``keep_latest``)
say what the job manager does for the kind beyond validating its params; the manager calls
them for any kind and never tests a kind's name. Drawing in the viewer is a hook of the
viewer itself (``web.results``): ``app`` does not import ``web``.

What a job carries from submission to its worker (``JobPayload``): the validated params as
JSON and the robot model the service resolved (so a worker needs no access to the service's
registry). The worker rebuilds the params model from that JSON (``execute``), attaches the
robot model to it (``Params.robot_model()``), runs the kind and checks what it returned
against the kind's ``Result`` before the result is stored: a result that does not match fails
the job, naming the field at fault.

Kinds are registered with ``register``, which refuses a name registered before. The modules
that define kinds are imported, explicitly, by ``app.jobs.catalog``; import ``KINDS`` from
there to see every kind.

Defined here: ``sleep`` and ``echo`` (diagnostics) and ``workspace``.
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Annotated, Any, Generic, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, JsonValue, PrivateAttr, ValidationError

from ..fields import StrictModel
from .caps import MAX_PARAMS_BYTES
from .graph import Step, check, whole

if TYPE_CHECKING:
    from kinematics.model import RobotModel

__all__ = [
    "JobKind",
    "JobCancelled",
    "JobResultError",
    "JobPayload",
    "Submission",
    "Params",
    "Result",
    "Progress",
    "KINDS",
    "MAX_SEED",
    "XYZ",
    "register",
    "get_kind",
    "execute",
    "load_job",
    "error_text",
    "absent_when_none",
    "pick",
    "SleepParams",
    "SleepResult",
    "EchoParams",
    "EchoResult",
    "WorkspaceParams",
    "WorkspaceResult",
]

Progress = Callable[[float, str], None]

#: Largest random seed a job takes (a 32-bit generator seed).
MAX_SEED = 2**32 - 1

#: A point or vector of a result, mm.
XYZ = Annotated[list[float], Field(min_length=3, max_length=3)]


class JobCancelled(Exception):
    """Raised inside a job by ``progress`` once the job is cancelled."""


class JobResultError(ValueError):
    """A job returned something its kind's ``Result`` does not describe."""


class Params(StrictModel):
    """Job parameters: unknown fields and NaN/inf are rejected (422 naming the field).

    A worker attaches the robot model the service resolved at submission; ``robot_model()``
    returns it."""

    _robot_model: RobotModel | None = PrivateAttr(None)
    _imported: tuple[Any, Any] | None = PrivateAttr(None)

    def attach_robot_model(self, model: RobotModel) -> None:
        self._robot_model = model

    def attach_imported(self, robot: Any, collision_model: Any) -> None:
        """Attach an imported robot and its collision model (from the job's payload)."""
        self._imported = (robot, collision_model)

    def imported(self) -> tuple[Any, Any] | None:
        """``(ImportedRobot, RobotCollisionModel)`` of an imported robot, else None."""
        return self._imported

    def robot_model(self) -> RobotModel:
        """The model of the job's robot: the one attached, else the built-in robot of that
        id (a kind run in-process); ValueError if there is neither."""
        if self._robot_model is not None:
            return self._robot_model
        from kinematics.library import builtin_model

        robot = getattr(self, "robot", None)
        try:
            return builtin_model(robot)
        except KeyError:
            raise ValueError(f"robot '{robot}': its model was not attached to the job and "
                             "it is not a built-in robot") from None


class Result(StrictModel):
    """A job's result: every field typed, nothing else, every number finite."""


def _is_none(value: Any) -> bool:
    return value is None


def absent_when_none(description: str | None = None) -> Any:
    """A result field that is left out of the JSON, rather than null, when it is None."""
    return Field(None, exclude_if=_is_none, description=description)


def pick(model: type[BaseModel], data: Mapping[str, Any]) -> dict[str, Any]:
    """The fields of ``model`` out of ``data`` (a library's JSON-ready dict, which may carry
    more than the job's result publishes)."""
    return {name: data[name] for name in model.model_fields if name in data}


def error_text(exc: ValidationError, prefix: str = "") -> str:
    """The first error of ``exc`` as ``where: what`` (``result.q.3.1: Input should be a
    finite number``), with the number of further errors."""
    errors = exc.errors()
    first = errors[0]
    where = ".".join(str(p) for p in (prefix, *first["loc"]) if p != "")
    more = f" (and {len(errors) - 1} more errors)" if len(errors) > 1 else ""
    return f"{where or prefix or 'value'}: {first['msg']}{more}"


P = TypeVar("P", bound=Params)
R = TypeVar("R", bound=Result)


@dataclass(frozen=True)
class Submission:
    """What a kind's ``prepare`` hook may consult when a job is submitted: the service's
    stored scenes (``app.scenes.SceneRegistry``; None when the service has none) and its
    robots (``app.registry.RobotRegistry``)."""

    scenes: Any
    registry: Any


@dataclass(frozen=True)
class JobKind(Generic[P, R]):
    """A kind of job. ``needs_robot``: params name a robot whose model is attached;
    ``max_params_bytes``: the most JSON its params may take (413 above); ``plot``: draws a
    succeeded job as PNG (None: the kind has no plot).

    Hooks the job manager calls by kind, never by name (each off by default):
    ``prepare(params, submission) -> params`` rewrites the submitted JSON params after the
    size checks and before validation, with what a worker cannot look up itself (a stored
    scene filled in); it raises ``ParamsLimitError`` naming the field. ``check(params,
    submission)`` checks the validated params model against the service's state (the
    problems against the robot's joints) and raises the same. ``needs_geometry``:
    an imported robot's description, collision model and meshes travel with the job
    (``JobPayload.robot_files``). ``keep_latest``: the service serves from the latest
    succeeded job of the kind per robot, so retention never prunes that one."""

    name: str
    params: type[P]
    result: type[R]
    run: Callable[[P, Progress], R]
    description: str
    needs_robot: bool = False
    max_params_bytes: int = MAX_PARAMS_BYTES
    plot: Callable[[P, R, RobotModel | None], bytes] | None = None
    #: The job as steps several workers can share (``app.jobs.graph``); None: one step,
    #: ``run``. A kind with a graph runs it inline in ``run``, so its result is the same
    #: however the steps are spread.
    graph: Callable[[P], list[Step]] | None = None
    prepare: Callable[[dict[str, Any], Submission], dict[str, Any]] | None = None
    check: Callable[[P, Submission], None] | None = None
    needs_geometry: bool = False
    keep_latest: bool = False

    def prepared(self, params: dict[str, Any], submission: Submission) -> dict[str, Any]:
        """The submitted ``params`` after the kind's ``prepare`` hook (as given without one)."""
        return params if self.prepare is None else self.prepare(params, submission)

    def steps(self, params: P) -> list[Step]:
        """The steps of a job with ``params``: its kind's graph, or ``run`` as one step."""
        steps = self.graph(params) if self.graph is not None else whole(self.run)
        check(steps)
        return steps

    def robot_id(self, params: P) -> str | None:
        """The robot the job's params name (None: no robot)."""
        return getattr(params, "robot", None)

    def load_params(self, data: Any) -> P:
        """The params model of ``data`` (stored or submitted JSON); ValidationError."""
        return self.params.model_validate(data)

    def load_result(self, data: Mapping[str, Any] | str | bytes) -> R:
        """The result model of a stored result (JSON text or parsed); ValidationError."""
        if isinstance(data, str | bytes):
            return self.result.model_validate_json(data)
        return self.result.model_validate(data)

    def result_json(self, result: Any) -> str:
        """The JSON text to store of what the runner returned, checked against ``result``;
        ``JobResultError`` naming the field when it does not match."""
        if isinstance(result, BaseModel):
            text = result.model_dump_json()
        else:
            try:
                text = json.dumps(result, allow_nan=False)
            except (TypeError, ValueError) as exc:
                raise JobResultError(f"the {self.name} job returned no JSON data: "
                                     f"{exc}") from None
        try:
            self.result.model_validate_json(text)
        except ValidationError as exc:
            raise JobResultError(f"the {self.name} job's result does not match its schema "
                                 f"({self.result.__name__}): "
                                 f"{error_text(exc, 'result')}") from None
        return text


KINDS: dict[str, JobKind] = {}


def register(kind: JobKind) -> JobKind:
    """Make ``kind`` available to POST /jobs; ValueError if its name is taken."""
    if kind.name in KINDS:
        raise ValueError(f"job kind {kind.name!r} is already registered (by "
                         f"{KINDS[kind.name].run.__module__})")
    KINDS[kind.name] = kind
    return kind


def get_kind(name: str) -> JobKind:
    """The kind called ``name``; KeyError if unknown."""
    return KINDS[name]


class JobPayload(BaseModel):
    """What a job carries to its worker: the validated params as JSON and the JSON of the
    robot model the service resolved (``kinematics.model.RobotModel.to_dict``), if any."""

    model_config = ConfigDict(extra="forbid")

    params: dict[str, JsonValue]
    robot_model: dict[str, JsonValue] | None = None
    #: An imported robot's description, collision model and collision meshes (base64 by
    #: name, ``app.registry.RobotRegistry.robot_files``), for kinds that need its geometry.
    robot_files: dict[str, str] | None = None

    @classmethod
    def from_stored(cls, data: Mapping[str, Any]) -> JobPayload:
        """The payload of a stored job; also reads the older layout (the params with the
        model under ``_model``) of jobs queued before this one existed."""
        if "params" in data and set(data) <= {"params", "robot_model", "robot_files"}:
            return cls.model_validate(data)
        params = dict(data)
        return cls(params=params, robot_model=params.pop("_model", None))


def load_job(name: str, payload: Mapping[str, Any]) -> tuple[JobKind, Params]:
    """The kind and the params model of a job's payload, with its robot model (and an
    imported robot's geometry) attached: what a worker needs to run any of its steps."""
    kind = get_kind(name)
    job = JobPayload.from_stored(payload)
    params = kind.load_params(job.params)
    if job.robot_model is not None:
        from kinematics.model import RobotModel

        params.attach_robot_model(RobotModel.from_dict(job.robot_model))
    if job.robot_files:
        params.attach_imported(*_imported_of(job.robot_files))
    return kind, params


def execute(name: str, payload: Mapping[str, Any], progress: Progress) -> str:
    """Run a job in one process: rebuild the params model from the payload, attach the robot
    model, run the kind; the result's JSON text, checked against the kind's ``Result``."""
    kind, params = load_job(name, payload)
    return kind.result_json(kind.run(params, progress))


_IMPORTED: dict[str, tuple[Any, Any]] = {}


def _imported_of(files: Mapping[str, str]) -> tuple[Any, Any]:
    """``(ImportedRobot, RobotCollisionModel)`` rebuilt from a payload's ``robot_files``
    (the last few kept per process: a batch of jobs on one robot decodes it once)."""
    import base64
    import hashlib
    import json

    key = hashlib.sha256(files["collision"].encode()).hexdigest() + \
        hashlib.sha256(files["description"].encode()).hexdigest()
    hit = _IMPORTED.get(key)
    if hit is not None:
        return hit
    from kinematics.urdf_import import ImportedRobot, mesh_from_bytes
    from planning.collision import RobotCollisionModel

    meshes = {k[5:]: mesh_from_bytes(base64.b64decode(v)) for k, v in files.items()
              if k.startswith("mesh:")}
    robot = ImportedRobot.from_dict(json.loads(base64.b64decode(files["description"])), meshes)
    cm = RobotCollisionModel.from_bytes(base64.b64decode(files["collision"]), robot)
    if len(_IMPORTED) >= 4:
        _IMPORTED.pop(next(iter(_IMPORTED)))
    _IMPORTED[key] = (robot, cm)
    return robot, cm


# ---- sleep: a diagnostic kind to check the pool itself ----------------------------------
class SleepParams(Params):
    seconds: float = Field(1.0, ge=0, le=3600, description="How long to run")
    steps: int = Field(10, ge=1, le=10_000, description="Progress reports on the way")
    outcome: Literal["succeed", "raise", "exit"] = Field(
        "succeed",
        description="'raise': end with an error; 'exit': the worker process dies abruptly "
        "(to check that only this job fails)",
    )


class SleepResult(Result):
    slept: float = Field(description="s")
    pid: int = Field(description="The worker process")


def run_sleep(params: SleepParams, progress: Progress) -> SleepResult:
    """Sleep in steps, reporting progress; optionally fail in one of two ways at the end."""
    steps = params.steps
    for k in range(steps):
        time.sleep(params.seconds / steps)
        progress((k + 1) / steps, f"step {k + 1} of {steps} (pid {os.getpid()})")
    if params.outcome == "raise":
        raise RuntimeError("the sleep job was asked to fail")
    if params.outcome == "exit":
        os._exit(3)  # no cleanup, no message: as a crash would
    return SleepResult(slept=params.seconds, pid=os.getpid())


register(JobKind("sleep", SleepParams, SleepResult, run_sleep,
                 "Sleep with progress; a diagnostic of the job pool"))


# ---- echo ------------------------------------------------------------------------------
class EchoParams(Params):
    value: JsonValue = Field(None, description="Any JSON value, returned as the result "
                             "(within the limits of every job's params: size, nesting, finite "
                             "numbers)")


class EchoResult(Result):
    value: JsonValue = Field(description="The params' value")


def run_echo(params: EchoParams, progress: Progress) -> EchoResult:
    progress(1.0, "done")
    return EchoResult(value=params.value)


register(JobKind("echo", EchoParams, EchoResult, run_echo, "Return the params' value"))


# ---- workspace -------------------------------------------------------------------------
class WorkspaceParams(Params):
    robot: str = Field(max_length=200, description="Robot id")
    samples: int = Field(30_000, ge=1, le=20_000_000, description="Monte Carlo samples")
    seed: int = Field(0, ge=0, le=MAX_SEED)
    voxel: float | None = Field(None, gt=0, le=1e6, description="Voxel edge, mm")
    return_points: int = Field(20_000, ge=0, le=200_000)
    projections: bool = True


class WorkspaceProjection(Result):
    counts: list[list[int]] = Field(description="Samples per cell")
    first_edges: list[float] = Field(description="Cell edges along the first axis, mm")
    second_edges: list[float] = Field(description="Cell edges along the second axis, mm")


class WorkspaceResult(Result):
    """The answer of ``POST /robots/{id}/workspace``, with the robot id."""

    robot: str
    samples: int
    seed: int
    min: XYZ = Field(description="Least x, y, z reached, mm")
    max: XYZ = Field(description="Largest x, y, z reached, mm")
    radial: list[float] = Field(min_length=2, max_length=2,
                                description="[min, max] distance from the base z axis, mm")
    vertical: list[float] = Field(min_length=2, max_length=2,
                                  description="[min, max] height along the base z axis, mm")
    voxel: float = Field(description="Voxel edge, mm")
    volume: float = Field(description="mm^3, voxel estimate")
    points: list[XYZ] = Field(description="Up to return_points tool positions, mm")
    projections: dict[str, WorkspaceProjection] | None = absent_when_none(
        "Occupancy images 'xy', 'xz', 'yz' (absent unless asked for)")


#: Work of merging the extents (choosing the returned samples), of the final assembly and
#: of each returned point in it, as samples' worth of the first pass.
_WS_MERGE, _WS_FINAL, _WS_POINT = 50_000, 300_000, 7


def workspace_graph(params: WorkspaceParams) -> list[Step]:
    """The steps of a workspace job: one when it fits in one part
    (``kinematics.workspace.PART`` samples); else per part the extents, a merge (voxel,
    returned samples), per part the cells, projection counts and returned points, and the
    result (``kinematics.workspace``'s passes)."""
    from kinematics.workspace import part_count, part_range, pass2_work

    from .graph import Ref

    n = part_count(params.samples)
    if n == 1:
        return [Step(workspace_whole)]
    sizes = [b - a for a, b in (part_range(params.samples, k) for k in range(n))]
    pass2 = pass2_work(params.projections)
    steps = [Step(workspace_bounds_step, (k,), weight=sizes[k], label=f"part {k + 1} of {n}")
             for k in range(n)]
    steps.append(Step(workspace_grid_step, ([Ref(k) for k in range(n)],), weight=_WS_MERGE,
                      label="extents"))
    steps += [Step(workspace_cells_step, (k, Ref(n)), weight=pass2 * sizes[k],
                   label=f"part {k + 1} of {n}") for k in range(n)]
    final = _WS_FINAL + _WS_POINT * min(params.return_points, params.samples)
    steps.append(Step(workspace_result_step, (Ref(n), [Ref(n + 1 + k) for k in range(n)]),
                      weight=final, label="volume"))
    return steps


def workspace_whole(params: WorkspaceParams, progress: Progress) -> WorkspaceResult:
    """A workspace of one part in one step: ``sample_workspace``, as the synchronous
    endpoint answers."""
    from kinematics.workspace import sample_workspace

    ws = sample_workspace(params.robot_model(), params.samples, seed=params.seed,
                          voxel=params.voxel, return_points=params.return_points,
                          projections=params.projections,
                          progress=lambda f: progress(f, "sampling"), max_samples=math.inf)
    return _workspace_result(params, ws)


def workspace_bounds_step(params: WorkspaceParams, index: int, progress: Progress) -> Any:
    """Pass 1 of part ``index``: ``kinematics.workspace.PartBounds``."""
    from kinematics.workspace import part_bounds

    return part_bounds(params.robot_model(), params.samples, params.seed, index,
                       progress=lambda f: progress(f, "extents"))


def workspace_grid_step(params: WorkspaceParams, bounds: list, progress: Progress) -> Any:
    """The parts' extents merged: ``kinematics.workspace.WorkspaceGrid``."""
    from kinematics.workspace import workspace_grid

    grid = workspace_grid(bounds, params.samples, params.seed, params.voxel,
                          params.return_points)
    progress(1.0, "merged")
    return grid


def workspace_cells_step(params: WorkspaceParams, index: int, grid: Any,
                         progress: Progress) -> Any:
    """Pass 2 of part ``index``: ``kinematics.workspace.PartCells``."""
    from kinematics.workspace import part_cells

    return part_cells(params.robot_model(), grid, index, params.projections,
                      progress=lambda f: progress(f, "cells"))


def workspace_result_step(params: WorkspaceParams, grid: Any, cells: list,
                          progress: Progress) -> WorkspaceResult:
    """The volume (union of the parts' voxels), the projections summed, the points."""
    from kinematics.workspace import assemble

    out = _workspace_result(params, assemble(grid, cells, params.projections))
    progress(1.0, "done")
    return out


def _workspace_result(params: WorkspaceParams, ws: Any) -> WorkspaceResult:
    from kinematics.workspace import workspace_report

    report = workspace_report(ws, params.return_points, params.projections)
    return WorkspaceResult(robot=params.robot_model().id, **pick(WorkspaceResult, report))


def run_workspace(params: WorkspaceParams, progress: Progress) -> WorkspaceResult:
    """Monte Carlo workspace of a robot; the answer of POST /robots/{id}/workspace (the same
    figures for the same seed, however many parts it is computed in, and where)."""
    from .graph import run_inline

    return run_inline(workspace_graph(params), params, progress)


register(JobKind("workspace", WorkspaceParams, WorkspaceResult, run_workspace,
                 "Monte Carlo workspace (large N)", needs_robot=True, graph=workspace_graph))
