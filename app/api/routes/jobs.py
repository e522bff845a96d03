"""Long-running work as jobs: submit, list, follow, fetch the result, cancel."""

from __future__ import annotations

import json
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Path, Request, Response
from pydantic import Field

from ...jobs.kinds import KINDS
from ...jobs.manager import JobManager, JobParamsError, JobStateError, QueueFullError
from ..deps import RegistryDep, require_api_key
from ..errors import http_error, not_found
from ..schemas import Body, JobRecordOut

router = APIRouter(prefix="/jobs", tags=["jobs"])


class JobRequest(Body):
    kind: str = Field(description="Job kind, e.g. 'workspace' (see GET /jobs/kinds)")
    params: dict[str, Any] = Field(default_factory=dict, description="Parameters of the kind")


def get_manager(request: Request) -> JobManager:
    return request.app.state.jobs


ManagerDep = Annotated[JobManager, Depends(get_manager)]
JobId = Annotated[str, Path(description="Job id", max_length=64)]


@router.post("", status_code=202, response_model=JobRecordOut,
             dependencies=[Depends(require_api_key)],
             responses={404: {"description": "Unknown robot in params"},
                        422: {"description": "Invalid kind or params"},
                        429: {"description": "Queue full"}})
def submit_job(body: JobRequest, jobs: ManagerDep) -> dict:
    """Queue a job; its params are checked before it is queued."""
    try:
        job = jobs.submit(body.kind, body.params)
    except JobParamsError as exc:
        raise http_error(exc.status, ["body", *exc.loc], exc.message,
                     "not_found" if exc.status == 404 else "value_error") from None
    except QueueFullError as exc:
        raise http_error(429, ["body", "kind"], str(exc), "queue_full") from None
    return job.to_dict()


@router.get("", response_model=list[JobRecordOut])
def list_jobs(jobs: ManagerDep) -> list[dict]:
    """Every job, oldest first (without results)."""
    return [j.to_dict() for j in jobs.list()]


@router.get("/kinds")
def job_kinds() -> list[dict]:
    """The job kinds and the JSON schema of their params."""
    return [{"kind": k.name, "description": k.description,
             "params": k.params.model_json_schema()} for k in KINDS.values()]


@router.get("/{job_id}", response_model=JobRecordOut, responses={404: {"description": "Unknown"}})
def get_job(job_id: JobId, jobs: ManagerDep) -> dict:
    """A job's record: status, progress (0..1) and message, times, error."""
    try:
        return jobs.get(job_id).to_dict()
    except KeyError:
        raise not_found("job", job_id) from None


@router.get("/{job_id}/result", responses={404: {"description": "Unknown job"},
                                          409: {"description": "Not succeeded (yet)"}})
def get_job_result(job_id: JobId, jobs: ManagerDep) -> Response:
    """The result JSON of a succeeded job; 409 until then."""
    try:
        text = jobs.result(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
    return Response(text, media_type="application/json")


#: Job kinds ``GET /jobs/{id}/plot`` can draw.
PLOTTABLE_KINDS = ("tracking",)


@router.get("/{job_id}/plot", response_class=Response,
            responses={200: {"content": {"image/png": {}}},
                       404: {"description": "Unknown job"},
                       409: {"description": "Not succeeded (yet)"},
                       422: {"description": "A kind without a plot"}})
def get_job_plot(job_id: JobId, jobs: ManagerDep, registry: RegistryDep) -> Response:
    """A succeeded job's result as a PNG. ``tracking``: joint angles, joint speeds (limits
    dashed), error per axis and tool error against time (paper 003, Figure 7)."""
    from ...plots import tracking_png

    try:
        job = jobs.get(job_id)
        text = jobs.result(job_id)
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
    if job.kind not in PLOTTABLE_KINDS:
        raise http_error(422, ["path", "job_id"], f"jobs of kind '{job.kind}' have no plot; "
                         f"plots exist for {', '.join(PLOTTABLE_KINDS)}", "value_error")
    result = json.loads(text)
    if not {"x_desired", "x_actual"} <= result.keys():  # stored before the paths were kept
        raise http_error(422, ["path", "job_id"], "this tracking result predates the "
                         "recorded tool path; run the job again to plot it", "value_error")
    dof = len(result["q"][0])
    names, limits = [f"j{i + 1}" for i in range(dof)], None
    try:
        model = registry.get(result["robot"])
    except KeyError:  # deleted since: plot without its joint names and speed limits
        model = None
    if model is not None and model.dof == dof:
        names, limits = [j.name for j in model.joints], model.velocity_limits
    tune = f", tuned by {result['tune'].upper()}" if result.get("tune") else ""
    controller = {"pi": "PI", "default": "default (PI + feed-forward)"}.get(
        result["controller"], result["controller"])
    title = f"{result['robot']}: {result['task']['kind']} task, {controller} controller{tune}"
    png = tracking_png(result["t"], result["q"], result["x_desired"], result["x_actual"],
                       names, title, limits)
    return Response(png, media_type="image/png")


@router.delete("/{job_id}", response_model=JobRecordOut,
               dependencies=[Depends(require_api_key)],
               responses={404: {"description": "Unknown job"},
                          409: {"description": "Already ended"}})
def cancel_job(job_id: JobId, jobs: ManagerDep) -> dict:
    """Cancel a queued job at once, or stop a running one (within 2 s)."""
    try:
        return jobs.cancel(job_id).to_dict()
    except KeyError:
        raise not_found("job", job_id) from None
    except JobStateError as exc:
        raise http_error(409, ["path", "job_id"], str(exc), "conflict") from None
