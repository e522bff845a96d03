"""Service settings: defaults, overridden by ``KINOPLAN_<NAME>`` variables, then CLI flags."""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

from .limits import DEFAULT_BODY_CAP, ROUTE_BODY_CAPS

__all__ = ["Settings"]

#: The largest body cap of any route (``app.limits``), and that route: the service-wide cap
#: defaults to it, so the default lowers no route's cap and ``--help`` states the real one.
LARGEST_BODY_CAP, LARGEST_BODY_ROUTE = max((cap, route) for route, cap in ROUTE_BODY_CAPS.items())


class Settings(BaseSettings):
    """Everything the service reads at start-up.

    Each field is also a flag of ``python -m kinoplan`` and ``python -m app``
    (``app.__main__``: ``data_dir`` is ``--data-dir``, its help the field's
    ``description``) and reads ``KINOPLAN_<NAME>``;
    a field with ``repr=False`` is a secret whose value is never shown.
    """

    model_config = SettingsConfigDict(env_prefix="KINOPLAN_", extra="ignore")

    host: str = Field("127.0.0.1", description="API (and viewer) bind address")
    port: int = Field(8000, ge=1, le=65535, description="API port")
    viewer_port: int = Field(8080, ge=1, le=65535, description="3D viewer port")
    no_viewer: bool = Field(False, description="do not start the 3D viewer")
    data_dir: Path = Field(
        Path("./data"), description="directory of the SQLite store of custom robots and jobs")
    workers: int = Field(default_factory=lambda: os.cpu_count() or 1, ge=1,
                         description="job worker processes (one per core unless set)")
    jobs_backend: str = Field(
        "local", description="'local', or a Dask scheduler: 'dask://HOST:PORT' ('tcp://' the "
        "same; 'tls://HOST:PORT' with Dask's TLS settings, DASK_DISTRIBUTED__COMM__TLS__*)")
    cluster_deadline_s: float = Field(
        600.0, gt=0, le=7 * 86_400,
        description="seconds the Dask backend waits for a lost (or never reached) scheduler "
        "before the jobs running or queued fail, naming it; submissions answer 503 meanwhile")
    api_key: str | None = Field(
        None, repr=False,
        description="key every request that changes state must bear (Authorization: Bearer); "
        "prefer the environment variable: a flag shows in the process list")
    max_queued_jobs: int = Field(1000, ge=1, description="jobs waiting at once (POST /jobs "
                                 "answers 429 beyond)")
    max_body_bytes: int = Field(
        LARGEST_BODY_CAP, ge=1024,
        description="largest request body of any route, bytes (413 above). Each route has its "
        f"own cap, which this lowers: at most {LARGEST_BODY_CAP >> 20} MiB "
        f"({LARGEST_BODY_ROUTE}), {DEFAULT_BODY_CAP >> 10} KiB for most (app.limits)")
    job_time_limit_s: float = Field(
        3600.0, ge=1, le=7 * 86_400,
        description="seconds a job may run, and the most a job may ask for (time_limit_s of "
        "POST /jobs); a job still running then fails with 'time limit of N s exceeded'")
    job_retention_days: float = Field(
        30.0, ge=0, le=36_500,
        description="days a finished job (record and result) is kept after it ended, then "
        "deleted; 0: no age limit. The latest succeeded ik_train job of each robot stays")
    job_retention_count: int = Field(
        10_000, ge=0, le=10**9,
        description="finished jobs kept at most (those that ended last); 0: no count limit")
    allowed_hosts: str | None = Field(
        None,
        description="comma-separated Host names the API answers ('*' = any; unset: the "
        "loopback names when bound to loopback, any otherwise; app.limits.host_allow_list)")
    header_timeout_s: float = Field(10.0, gt=0, le=600,
                                    description="seconds a client may take to send a request head")
    idle_timeout_s: float = Field(30.0, gt=0, le=3600,
                                  description="seconds a client may stay silent mid-body")
    max_connections: int = Field(512, ge=1, description="open connections served at once "
                                 "(503 above)")
    compute_workers: int = Field(
        2, ge=1, le=64,
        description="worker processes for heavy synchronous requests (large workspaces, FK/IK "
        "batches, plots)")
    max_waiting_computations: int = Field(
        32, ge=1, description="heavy requests that may wait for a compute worker (503 beyond)")
    prestart_compute: bool = Field(
        True, description="start the compute workers and load their compiled kernels as the "
        "service starts (in the background), so that no synchronous request waits seconds for "
        "a worker to start")
    prebuild_collision: bool = Field(
        True, description="build an imported robot's collision model right after its import "
        "(in a compute worker; stored with the robot) rather than at its first collision query")
    allowed_origins: str | None = Field(
        None,
        description="comma-separated origins of the pages that may open the 3D viewer, e.g. "
        "https://viewer.example.com (unset: the viewer's own addresses; web.gate)")
