"""Dask worker preload (``dask worker ... --preload app.jobs.dask_preload``; ``python -m
app.worker`` adds it): imports the job kinds when the worker starts and starts one step
runner per worker thread, so a worker's first step starts at once rather than after
seconds of imports (which would also stall the worker's event loop while it unpickles the
first task)."""

from __future__ import annotations

from typing import Any

from . import dask_backend  # noqa: F401 - every kind, and run_step, imported now
from .runner import prestart


def dask_setup(worker: Any) -> None:
    prestart(max(1, int(getattr(worker.state, "nthreads", 1))))
