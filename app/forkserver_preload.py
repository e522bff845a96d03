"""Imported first by multiprocessing's forkserver (``app.lifetime.forkserver_context``): the
server dies with the service, and each process it forks dies with the server
(``app.lifetime.guard_forkserver``)."""

from __future__ import annotations

from .lifetime import guard_forkserver

guard_forkserver()
