"""What the service asks of a 3D viewer, without knowing which one runs.

The viewer (``web.viewer.Viewer``) sits above the service: it reads the service's robots,
jobs and scenes, and the service never imports it. The program that starts both
(``python -m kinoplan``) hands the service a started viewer through ``app.__main__.serve``'s
``start_viewer``; ``POST /viewer/show`` then talks to it through ``ViewerPort`` and answers
409 for ``JobNotReady``, which the viewer raises. Started without a viewer (``python -m app``,
or ``--no-viewer``), ``app.state.viewer`` is None and the route answers 503.
"""

from __future__ import annotations

from typing import Any, Protocol

__all__ = ["JobNotReady", "ViewerPort", "ViewerStarter"]


class JobNotReady(RuntimeError):
    """The job exists but has not succeeded; ``status`` says where it is."""

    def __init__(self, job_id: str, status: str, error: str | None = None) -> None:
        why = f": {error}" if error else ""
        super().__init__(f"job {job_id} is {status}; only a succeeded job can be shown{why}")
        self.status = status


class ViewerPort(Protocol):
    """A running viewer, as the service's routes and its start-up see it. Each ``show_*``
    answers what it now shows; KeyError for an unknown job or scene, ValueError for a
    request the viewer cannot draw."""

    @property
    def port(self) -> int:
        """The port browsers open."""
        ...

    def show_job(self, job_id: str, problem: int | None = None) -> dict:
        """A finished job's result (``problem``: one of a motion batch's); ``JobNotReady``
        if it has not succeeded."""
        ...

    def show_motion(self, answer: Any) -> dict:
        """The answer of a motion request (``app.api.schemas.MotionAnswerIn``)."""
        ...

    def select(self, key: str, q: Any = None) -> dict:
        """Robot or rig ``key`` at ``q`` (default mid-limits)."""
        ...

    def show_scene(self, scene_id: str | None) -> dict:
        """A stored scene (None clears it)."""
        ...

    def stop(self) -> None:
        """Stop serving."""
        ...


class ViewerStarter(Protocol):
    """Starts a viewer for a service about to serve: ``settings`` (``app.config.Settings``:
    host, viewer port, API key, allowed origins) and the application's ``state`` (its
    registry, jobs and scenes). Called once, before the API listens."""

    def __call__(self, settings: Any, state: Any) -> ViewerPort: ...
