"""Liveness."""

from __future__ import annotations

from fastapi import APIRouter

from ... import __version__
from ..deps import SettingsDep
from ..schemas import Health

router = APIRouter(tags=["service"])


@router.get("/health", response_model=Health)
def health(settings: SettingsDep) -> Health:
    """Service status, version and job backend."""
    return Health(status="ok", version=__version__, jobs_backend=settings.jobs_backend)
