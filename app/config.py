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
