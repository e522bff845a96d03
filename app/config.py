"""Service settings: defaults, overridden by ``KINOPLAN_<NAME>`` variables, then CLI flags."""

from __future__ import annotations

import os
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict

__all__ = ["Settings"]


class Settings(BaseSettings):
    """Everything the service reads at start-up."""

    model_config = SettingsConfigDict(env_prefix="KINOPLAN_", extra="ignore")

    host: str = "127.0.0.1"
    port: int = Field(8000, ge=1, le=65535)
    viewer_port: int = Field(8080, ge=1, le=65535)
    no_viewer: bool = False
    data_dir: Path = Path("./data")
    workers: int = Field(default_factory=lambda: os.cpu_count() or 1, ge=1)
    jobs_backend: str = "local"
    api_key: str | None = None
    max_queued_jobs: int = Field(1000, ge=1)
    max_body_bytes: int = Field(64 * 1024 * 1024, ge=1024)
    #: Seconds a job may run, and the most a job may ask for (``time_limit_s`` of POST /jobs);
    #: a job still running then fails with "time limit of N s exceeded".
    job_time_limit_s: float = Field(3600.0, ge=1, le=7 * 86_400)
    #: ``Host`` names served (comma-separated, ``*`` = any); unset: the loopback names when
    #: bound to a loopback address, any name otherwise (see ``app.limits.host_allow_list``).
    allowed_hosts: str | None = None
    #: Seconds a client may take to send a request head, and may stay silent mid-body.
    header_timeout_s: float = Field(10.0, gt=0, le=600)
    idle_timeout_s: float = Field(30.0, gt=0, le=3600)
    #: Open connections served at once (503 above).
    max_connections: int = Field(512, ge=1)
    #: Worker processes for heavy synchronous requests (large workspaces, FK/IK batches,
    #: plots), and how many such requests may wait for one (503 beyond).
    compute_workers: int = Field(2, ge=1, le=64)
    max_waiting_computations: int = Field(32, ge=1)
    #: Pages that may open the 3D viewer (comma-separated origins, e.g.
    #: ``https://viewer.example.com``); unset: the viewer's own addresses (``web.gate``).
    allowed_origins: str | None = None
