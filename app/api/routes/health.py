"""Liveness and readiness: ``GET /health`` checks the store and the job backend."""

from __future__ import annotations

import asyncio
import threading
import time
from concurrent.futures import Future

from fastapi import APIRouter, Request, Response

from ... import __version__
from ...jobs.manager import JobManager
from ...responses import FastJSONRoute
from ...store import HEALTH_TTL_S, Store
from ..schemas import Health, JobsHealth, StoreHealth

router = APIRouter(tags=["service"], route_class=FastJSONRoute)

#: Longest wait (s) for a store check; a store that takes longer counts as unhealthy.
STORE_CHECK_WAIT_S = 2.0


def _check_in_background(store: Store) -> Future:
    """``store.health()`` on a daemon thread of its own, so that neither a busy request thread
    pool nor a hung file system can hold up the answer (or the service's exit)."""
    done: Future = Future()
    done.set_running_or_notify_cancel()

    def run() -> None:
        try:
            done.set_result(store.health(HEALTH_TTL_S))
        except Exception as exc:  # reported as the store's error
            done.set_exception(exc)

    threading.Thread(target=run, name="kinoplan-health", daemon=True).start()
    return done


async def _store_health(store: Store) -> StoreHealth:
    last = store.health_snapshot
    if last is not None and time.monotonic() - last[0] < HEALTH_TTL_S:
        why = last[1]
    else:
        try:
            why = await asyncio.wait_for(asyncio.wrap_future(_check_in_background(store)),
                                         STORE_CHECK_WAIT_S)
        except TimeoutError:
            why = f"the store did not answer within {STORE_CHECK_WAIT_S:g} s"
        except Exception as exc:
            why = f"{type(exc).__name__}: {exc}"
    usage = store.usage  # read by the same check
    if usage is None:
        return StoreHealth(ok=why is None, error=why)
    return StoreHealth(ok=why is None, error=why, bytes=usage.bytes,
                       free_bytes=usage.free_bytes, job_counts=usage.jobs)


def _jobs_health(jobs: JobManager) -> JobsHealth:
    backend = jobs.backend
    if backend is None:  # not started (an app built but not served) or stopped
        return JobsHealth(ok=True, running=False)
    if not backend.alive():
        return JobsHealth(ok=False, running=False,
                          error=f"the {backend.name} job supervisor has stopped")
    unavailable = jobs.unavailable()  # the Dask backend's scheduler out of reach
    if unavailable is not None:
        return JobsHealth(ok=False, running=True, workers=0, error=unavailable)
    workers = backend.parallelism()
    if backend.failing is not None:
        return JobsHealth(ok=False, running=True, workers=workers, error="the job "
                          "supervisor's passes are failing and retried with back-off; see "
                          "the service log")
    return JobsHealth(ok=True, running=True, workers=workers)


@router.get("/health", response_model=Health,
            responses={503: {"model": Health, "description": "The store or the job backend "
                             "does not work; `store` and `jobs` say which"}})
async def health(request: Request, response: Response) -> Health:
    """Service status, version and job backend, with a cheap real check of the store (read,
    writable, room on disk; reused for a second) and of the job backend: 200 when both
    work, else 503 with ``status: "degraded"``."""
    # Async and free of dependencies that would run on the request thread pool: /health
    # answers promptly however busy the service is.
    state = request.app.state
    store = await _store_health(state.store)
    jobs = _jobs_health(state.jobs)
    ok = store.ok and jobs.ok
    if not ok:
        response.status_code = 503
    return Health(status="ok" if ok else "degraded", version=__version__,
                  jobs_backend=state.settings.jobs_backend, store=store, jobs=jobs)
