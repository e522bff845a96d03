"""Builds the FastAPI application: ``create_app(settings)``; ``app`` uses the defaults."""

from __future__ import annotations

from collections.abc import AsyncIterator, Sequence
from contextlib import asynccontextmanager
from importlib.resources import files

from fastapi import Depends, FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.docs import (
    get_redoc_html,
    get_swagger_ui_html,
    get_swagger_ui_oauth2_redirect_html,
)
from fastapi.responses import HTMLResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException as StarletteHTTPException

from kinematics.errors import FieldError

from . import __version__
from .api.deps import require_api_key
from .api.routes import (
    collision,
    cylinders,
    drill_plans,
    exports,
    health,
    jobs,
    kinematics,
    motion,
    replay,
    rigs,
    robots,
    round_plan,
    scenes,
    trajectories,
    viewer,
)
from .api.schemas import ErrorOut
from .compute import ComputeBusy, ComputeFailed, ComputePool
from .config import Settings
from .jobs.manager import JobManager
from .limits import RequestGuard, body_caps, host_allow_list
from .registry import RobotRegistry
from .scenes import SceneRegistry
from .store import Store, StoreError

__all__ = ["create_app", "app"]  # noqa: F822 (``app`` is built lazily by __getattr__)

#: Error answers any operation may give (documented once for all of them in OpenAPI).
ERROR_RESPONSES: dict[int | str, dict] = {
    code: {"model": ErrorOut, "description": text}
    for code, text in {
        400: "Body could not be parsed", 401: "API key required", 403: "Read-only",
        404: "Unknown robot, rig or job", 409: "Conflict or not ready", 413: "Too large",
        429: "Job queue full", 503: "Part of the service not running",
    }.items()
}

DESCRIPTION = """Kinematics and motion planning for heavy-duty hydraulic arms and industrial
robots. Units: mm, rad, s. Poses are 4x4 homogeneous matrices as nested lists (row-major)."""


def _is_branch_tag(part: object) -> bool:
    return isinstance(part, str) and ("[" in part or part in {"float", "int", "str", "bool"})


def simplify_errors(errors: Sequence[dict]) -> list[dict]:
    """Pydantic's errors for a field typed as a union (e.g. one configuration or a list of
    them) list every branch's failures under a type tag in ``loc``. Keep the branch that came
    closest (fewest errors) and drop the tags, so the message names the field plainly."""
    groups: dict[tuple, dict[str, list[dict]]] = {}
    plain: list[dict] = []
    for e in errors:
        loc = list(e.get("loc", []))
        item = {"loc": loc, "msg": e.get("msg", ""), "type": e.get("type", "")}
        why = (e.get("ctx") or {}).get("error")
        if item["type"] == "json_invalid" and why:
            item["msg"] = f"{item['msg']}: {why}"   # why, not only that it failed
        tag_at = next((i for i, part in enumerate(loc) if _is_branch_tag(part)), None)
        if tag_at is None:
            plain.append(item)
            continue
        item["loc"] = loc[:tag_at] + loc[tag_at + 1 :]
        groups.setdefault(tuple(loc[:tag_at]), {}).setdefault(str(loc[tag_at]), []).append(item)
    for branches in groups.values():
        # Fewest errors wins; on a tie, the branch that got deeper into the input.
        plain.extend(
            min(branches.values(), key=lambda es: (len(es), -max(len(e["loc"]) for e in es)))
        )
    return plain


#: Most errors one 422 lists; the rest are counted in a last item.
MAX_ERRORS = 30


def validation_answer(errors: Sequence[dict]) -> tuple[int, list[dict]]:
    """Status and ``detail`` of a failed validation: at most ``MAX_ERRORS`` items (plus one
    counting the rest); 413 when a list is over a documented per-call cap."""
    items = simplify_errors(errors)
    status = 413 if any(e["type"] == "too_large" for e in items) else 422
    if len(items) > MAX_ERRORS:
        rest = len(items) - MAX_ERRORS
        items = [*items[:MAX_ERRORS], {"loc": [], "msg": f"and {rest} more errors",
                                       "type": "too_many_errors"}]
    return status, items


#: Where the Swagger UI and ReDoc files are served from (the ``fastapi-offline`` package's).
DOCS_ASSETS = "/docs-assets"


def serve_docs(api: FastAPI) -> None:
    """``/docs`` (Swagger UI) and ``/redoc`` with their scripts and styles served by the
    service itself (``DOCS_ASSETS``), not fetched from a CDN: the pages work offline and on a
    closed site network."""
    static = files("fastapi_offline") / "static"
    api.mount(DOCS_ASSETS, StaticFiles(directory=str(static)), name="docs-assets")

    @api.get("/docs", include_in_schema=False)
    async def swagger_ui(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        return get_swagger_ui_html(
            openapi_url=f"{root}{api.openapi_url}", title=f"{api.title} - Swagger UI",
            oauth2_redirect_url=f"{root}{api.swagger_ui_oauth2_redirect_url}",
            swagger_js_url=f"{root}{DOCS_ASSETS}/swagger-ui-bundle.js",
            swagger_css_url=f"{root}{DOCS_ASSETS}/swagger-ui.css",
            swagger_favicon_url=f"{root}{DOCS_ASSETS}/favicon.png")

    @api.get(str(api.swagger_ui_oauth2_redirect_url), include_in_schema=False)
    async def swagger_ui_redirect() -> HTMLResponse:
        return get_swagger_ui_oauth2_redirect_html()

    @api.get("/redoc", include_in_schema=False)
    async def redoc(request: Request) -> HTMLResponse:
        root = request.scope.get("root_path", "")
        return get_redoc_html(
            openapi_url=f"{root}{api.openapi_url}", title=f"{api.title} - ReDoc",
            redoc_js_url=f"{root}{DOCS_ASSETS}/redoc.standalone.js",
            redoc_favicon_url=f"{root}{DOCS_ASSETS}/favicon.png", with_google_fonts=False)


def create_app(settings: Settings | None = None) -> FastAPI:
    """A new application with its own settings, robot registry and (optional) viewer."""
    settings = settings or Settings()

    @asynccontextmanager
    async def lifespan(api: FastAPI) -> AsyncIterator[None]:
        # The job backend (threads, worker processes, a cluster client) lives as long as the
        # served application, not as long as the object: building an app starts nothing.
        api.state.jobs.start()
        if settings.prestart_compute:
            api.state.compute.prestart()
        # The compiled kinematics kernels load (or, on a new machine, compile) in the
        # background; until then calls take the numpy path, with the same answers. This
        # process runs no motion plan (compute workers and job steps load every kernel),
        # and importing the job kinds loaded the sequencing search (planning.warm).
        from planning.warm import start_warm_up

        start_warm_up(["kinematics"])
        try:
            yield
        finally:
            api.state.jobs.stop()
            api.state.compute.shutdown()

    api = FastAPI(title="kinoplan", version=__version__, description=DESCRIPTION,
                  lifespan=lifespan, responses=ERROR_RESPONSES, docs_url=None, redoc_url=None)
    serve_docs(api)
    api.state.settings = settings
    api.state.store = Store.in_data_dir(settings.data_dir)
    api.state.registry = RobotRegistry(api.state.store)
    api.state.scenes = SceneRegistry(api.state.store)
    api.state.collision_builds = {}  # robot id -> the build of its collision model in flight
    api.state.jobs = JobManager(api.state.store, api.state.registry, settings.jobs_backend,
                                settings.workers, settings.max_queued_jobs,
                                time_limit_s=settings.job_time_limit_s,
                                cluster_deadline_s=settings.cluster_deadline_s,
                                retention_days=settings.job_retention_days,
                                retention_count=settings.job_retention_count)
    api.state.jobs.scenes = api.state.scenes
    api.state.viewer = None
    api.state.compute = ComputePool(settings.compute_workers, settings.max_waiting_computations)
    guarded = [Depends(require_api_key)]
    api.include_router(health.router)
    api.include_router(robots.router)
    api.include_router(robots.write_router, dependencies=guarded)
    api.include_router(rigs.router)
    api.include_router(kinematics.router)
    api.include_router(collision.router)
    api.include_router(motion.router)
    api.include_router(cylinders.router)
    api.include_router(drill_plans.router)
    api.include_router(trajectories.router)
    api.include_router(jobs.router)
    api.include_router(exports.router)
    api.include_router(round_plan.router)
    api.include_router(replay.router)
    api.include_router(replay.motion_router)
    api.include_router(scenes.router)
    api.include_router(scenes.write_router, dependencies=guarded)
    api.include_router(viewer.router, dependencies=guarded)

    @api.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
        # Errors raised by the framework itself (unparseable body, unknown path, method not
        # allowed) carry a string; give them the service's list shape too.
        detail = exc.detail
        if not isinstance(detail, list):
            detail = [{"loc": [], "msg": str(detail), "type": "http_error"}]
        return JSONResponse(status_code=exc.status_code, content={"detail": detail},
                            headers=getattr(exc, "headers", None))

    @api.exception_handler(FieldError)
    async def _field_error(request: Request, exc: FieldError) -> JSONResponse:
        # A domain check of kinematics or planning found a field of the request wrong and
        # named it (relative to the body); wherever it was raised, a worker process
        # included, the answer is a 422 at that field.
        return JSONResponse(status_code=422, content={"detail": [
            {"loc": ["body", *exc.loc], "msg": exc.message, "type": "value_error"}]})

    @api.exception_handler(StoreError)
    async def _store_error(request: Request, exc: StoreError) -> JSONResponse:
        # The store's file is gone, corrupt or read-only, or the disk is full: the service
        # cannot keep data until an operator acts. That is a 503, never a 500.
        msg = f"the data store is unavailable: {exc.reason}"
        return JSONResponse(status_code=503, headers={"Retry-After": "5"}, content={
            "detail": [{"loc": ["service", "store"], "msg": msg, "type": "unavailable"}]})

    @api.exception_handler(ComputeBusy)
    @api.exception_handler(ComputeFailed)
    async def _compute_unavailable(request: Request, exc: Exception) -> JSONResponse:
        return JSONResponse(status_code=503, headers={"Retry-After": "2"}, content={
            "detail": [{"loc": ["service", "compute"], "msg": str(exc), "type": "unavailable"}]})

    @api.exception_handler(RequestValidationError)
    async def _validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
        # FastAPI's default, minus the echoed input (a rejected 100,000-row body should not
        # come back in the error) and with at most MAX_ERRORS items.
        status, detail = validation_answer(exc.errors())
        return JSONResponse(status_code=status, content={"detail": detail})

    # Host allow-list, JSON bodies, a body cap per route (published in the OpenAPI document
    # as each operation's ``x-max-body-bytes``).
    build_openapi = api.openapi

    def openapi() -> dict:
        if api.openapi_schema is None:
            document = build_openapi()
            caps = body_caps(document["paths"], settings.max_body_bytes)
            for path, operations in document["paths"].items():
                for method, operation in operations.items():
                    if method in ("post", "put", "patch"):
                        operation["x-max-body-bytes"] = caps[path]
        return api.openapi_schema

    api.openapi = openapi  # type: ignore[method-assign]
    api.add_middleware(RequestGuard, max_bytes=settings.max_body_bytes,
                       templates=lambda: openapi()["paths"],
                       allowed_hosts=host_allow_list(settings.allowed_hosts, settings.host))
    return api


_default_app: FastAPI | None = None


def __getattr__(name: str) -> FastAPI:
    # ``app.main:app`` is built on first access, not at import: importing this module (tests,
    # tools) must not create the default data directory.
    global _default_app
    if name == "app":
        if _default_app is None:
            _default_app = create_app()
        return _default_app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
