"""Long-running work as jobs: submit, list, follow, fetch the result, cancel, delete.

Every kind's params and result are pydantic models (``app.jobs.catalog``): ``GET /jobs/kinds``
publishes both JSON schemas, and ``GET /jobs/{id}/result`` is documented as one of the result
models (the stored JSON text is served as it is; it was checked against its kind's model when
stored). ``GET /jobs/{id}/plot`` serves the kinds that have a ``plot`` hook.
"""

from __future__ import annotations

import functools
import operator
from typing import Annotated, Any, Literal

from fastapi import APIRouter, Depends, Path, Query, Request, Response
from pydantic import ConfigDict, Field, ValidationError
from starlette.concurrency import run_in_threadpool

from ...jobs.caps import MAX_PARAMS_BYTES, MAX_PARAMS_DEPTH, MAX_TIME_LIMIT_S
from ...jobs.catalog import KINDS
from ...jobs.kinds import error_text
from ...jobs.manager import (
    BackendUnavailable,
    JobManager,
    JobParamsError,
    JobStateError,
    QueueFullError,
)
from ...responses import FastJSONRoute
from ..deps import RegistryDep, require_api_key
from ..errors import http_error, not_found
from ..schemas import GLT_SWING, Body, JobKindOut, JobRecordOut, body_examples

router = APIRouter(prefix="/jobs", tags=["jobs"], route_class=FastJSONRoute)

#: Seconds a client is told to wait (``Retry-After``) while the job cluster is unreachable.
RETRY_AFTER_S = 5

#: Jobs ``GET /jobs`` answers by default, and at most, per page.
DEFAULT_PAGE = 100
MAX_PAGE = 1000
#: Largest ``offset`` of ``GET /jobs``.
MAX_OFFSET = 10**12

JobStatus = Literal["queued", "running", "succeeded", "failed", "cancelled"]

#: The result of a job: one of the kinds' result models (which one: the job's ``kind``).
JobResult = functools.reduce(operator.or_, (kind.result for kind in KINDS.values()))


class JobRequest(Body):
    model_config = ConfigDict(json_schema_extra=body_examples(
        {"kind": "workspace", "params": {"robot": "glt_palletizer", "samples": 100000,
                                         "seed": 1}},
        {"kind": "motion", "params": {"robot": "glt_palletizer", **GLT_SWING}}))

    kind: str = Field(max_length=64,
                      description="Job kind, e.g. 'workspace' (see GET /jobs/kinds)")
    params: dict[str, Any] = Field(
        default_factory=dict,
        description=f"Parameters of the kind: at most {MAX_PARAMS_BYTES:,} bytes of JSON "
        "(413 above; some kinds take more, see GET /jobs/kinds), nested at most "
        f"{MAX_PARAMS_DEPTH} levels, every number finite")
    time_limit_s: float | None = Field(
        None, ge=1, le=MAX_TIME_LIMIT_S,
        description="Seconds the job may run before it fails with 'time limit of N s "
        "exceeded'; default, and most, the service's job time limit (3600 s unless set)")


def get_manager(request: Request) -> JobManager:
    return request.app.state.jobs


ManagerDep = Annotated[JobManager, Depends(get_manager)]
JobId = Annotated[str, Path(description="Job id", max_length=64)]


@router.post("", status_code=202, response_model=JobRecordOut,
             dependencies=[Depends(require_api_key)],
             responses={404: {"description": "Unknown robot in params"},
                        422: {"description": "Invalid kind or params"},
                        429: {"description": "Queue full"},
                        503: {"description": "The job cluster is unreachable; retry later "
                              "(Retry-After)"}})
def submit_job(body: JobRequest, jobs: ManagerDep, request: Request) -> dict:
    """Queue a job; its params are checked before it is queued."""
    settings = request.app.state.settings
    try:
        job = jobs.submit(body.kind, body.params, body.time_limit_s,
                          settings.job_time_limit_s)
    except JobParamsError as exc:
        kind = {404: "not_found", 413: "too_large"}.get(exc.status, "value_error")
        raise http_error(exc.status, ["body", *exc.loc], exc.message, kind) from None
    except QueueFullError as exc:
        raise http_error(429, ["body", "kind"], str(exc), "queue_full") from None
    except BackendUnavailable as exc:
        raise http_error(503, ["body"], str(exc), "unavailable",
                         headers={"Retry-After": str(RETRY_AFTER_S)}) from None
    return job.to_dict()


@router.get("", response_model=list[JobRecordOut], responses={200: {"headers": {
    "X-Total-Count": {"description": "Jobs matching the filters, on every page",
                      "schema": {"type": "integer"}},
    "Link": {"description": '<URL of the next page>; rel="next" while more remain',
             "schema": {"type": "string"}},
}}})
def list_jobs(
    jobs: ManagerDep,
    request: Request,
    response: Response,
    status: Annotated[JobStatus | None, Query(description="Only jobs of this status")] = None,
    kind: Annotated[str | None, Query(max_length=64,
                                      description="Only jobs of this kind")] = None,
    limit: Annotated[int, Query(ge=1, le=MAX_PAGE, description="Jobs per page")] = DEFAULT_PAGE,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET,
                                 description="Matching jobs to skip")] = 0,
) -> list[dict]:
    """Jobs oldest first (without results), a page at a time: ``X-Total-Count`` gives how
    many match, ``Link: <...>; rel="next"`` the next page while more remain."""
    if kind is not None and kind not in KINDS:
        raise http_error(422, ["query", "kind"], f"unknown job kind {kind!r}; known: "
                         f"{', '.join(sorted(KINDS))}", "value_error")
    total = jobs.count(status, kind)
    page = jobs.list(status, kind, limit, offset)
    response.headers["X-Total-Count"] = str(total)
    if offset + len(page) < total:
        following = request.url.include_query_params(limit=limit, offset=offset + len(page))
        response.headers["Link"] = f'<{following}>; rel="next"'
    return [j.to_dict() for j in page]


@router.get("/kinds", response_model=list[JobKindOut])
def job_kinds() -> list[dict]:
    """The job kinds: the JSON schemas of their params and of their result, the most bytes
    of JSON the params may take, and whether ``GET /jobs/{id}/plot`` draws them."""
    out = []
    for k in KINDS.values():
        params = k.params.model_json_schema()
        out.append({"kind": k.name, "description": k.description, "params": params,
                    "params_schema": params,
                    "result_schema": k.result.model_json_schema(mode="serialization"),
                    "max_params_bytes": k.max_params_bytes, "plot": k.plot is not None})
    return out


@router.get("/{job_id}", response_model=JobRecordOut, responses={404: {"description": "Unknown"}})
def get_job(job_id: JobId, jobs: ManagerDep) -> dict:
    """A job's record: status, progress (0..1) and message, times, error."""
    try:
        return jobs.get(job_id).to_dict()
    except KeyError:
        raise not_found("job", job_id) from None


@router.get("/{job_id}/result", response_model=JobResult,
            responses={404: {"description": "Unknown job"},
                       409: {"description": "Not succeeded (yet)"}})
def get_job_result(job_id: JobId, jobs: ManagerDep) -> Response:
    """The result JSON of a succeeded job, of its kind's result schema (``result_schema`` in
    ``GET /jobs/kinds``); 409 until then."""
    try:
        text = jobs.result(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
    return Response(text, media_type="application/json")


@router.get("/{job_id}/plot", response_class=Response,
            responses={200: {"content": {"image/png": {}}},
                       404: {"description": "Unknown job"},
                       409: {"description": "Not succeeded (yet)"},
                       422: {"description": "A kind without a plot, or a result stored in an "
                             "older shape"}})
async def get_job_plot(job_id: JobId, jobs: ManagerDep, registry: RegistryDep,
                       request: Request) -> Response:
    """A succeeded job's result as a PNG, for the kinds with a plot (``plot`` in ``GET
    /jobs/kinds``). ``tracking``: joint angles, joint speeds (limits dashed), error per axis
    and tool error against time (paper 003, Figure 7)."""
    plot, *args = await run_in_threadpool(_plot_args, job_id, jobs, registry)
    # Drawing holds the interpreter for a while: in a worker process (app.compute).
    png = await request.app.state.compute.run(True, plot, *args)
    return Response(png, media_type="image/png")


def _plot_args(job_id: str, jobs: JobManager, registry) -> tuple:
    """The plot hook of job ``job_id``'s kind and its arguments: the typed params and result
    and the robot's model (None if deleted since); 404, 409 or 422 when there is no plot."""
    try:
        job = jobs.get(job_id)
        text = jobs.result(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
    kind = KINDS.get(job.kind)
    if kind is None or kind.plot is None:
        plottable = ", ".join(k.name for k in KINDS.values() if k.plot is not None)
        raise http_error(422, ["path", "job_id"], f"jobs of kind '{job.kind}' have no plot; "
                         f"plots exist for {plottable}", "value_error")
    try:
        params = kind.load_params(job.params)
        result = kind.load_result(text)
    except ValidationError as exc:  # stored by an older version of the service
        raise http_error(422, ["path", "job_id"], f"the stored job does not match the current "
                         f"'{kind.name}' schemas ({error_text(exc)}); run the job again to "
                         "plot it", "value_error") from None
    robot_id = kind.robot_id(params)
    try:
        model = registry.get(robot_id) if robot_id is not None else None
    except KeyError:  # deleted since: plot without its joint names and speed limits
        model = None
    return kind.plot, params, result, model


@router.delete("/{job_id}", response_model=JobRecordOut,
               dependencies=[Depends(require_api_key)],
               responses={204: {"description": "The job had ended: it is deleted, with its "
                                "result"},
                          404: {"description": "Unknown job"}})
def cancel_job(job_id: JobId, jobs: ManagerDep) -> Any:
    """Cancel a queued job at once, or stop a running one (within 2 s): 200 with its record.
    A job that has ended (succeeded, failed, cancelled) is deleted with its result: 204, and
    404 for it from then on."""
    try:
        job = jobs.delete(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
    return Response(status_code=204) if job is None else job.to_dict()
