"""A job of the service seen from the client: follow it, wait for it, read its result.

A job is long work the service runs in its pool (``POST /jobs``); its record
(``GET /jobs/{id}``) carries a status (``queued``, ``running``, then ``succeeded``,
``failed`` or ``cancelled``), a progress from 0 to 1 and a message. ``Job.wait`` polls that
record, drawing a one-line progress bar on stderr when stderr is a terminal.
"""

from __future__ import annotations

import json
import shutil
import sys
import time
import warnings
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:
    from .client import Client

__all__ = ["Job", "ENDED", "ProgressBar"]

#: The statuses a job does not leave.
ENDED = frozenset({"succeeded", "failed", "cancelled"})

#: A progress callback: called with the job's progress (0..1) and message at every poll.
ProgressCallback = Callable[[float, str], None]


class ProgressBar:
    """One line on ``stream``, redrawn in place: ``[#####-----]  50%  running  message``.

    Called with a job record; ``close`` ends the line. The line is cut to the terminal's
    width so that it never wraps (a wrapped line cannot be redrawn with ``\\r``)."""

    def __init__(self, stream: TextIO, label: str = "", width: int = 24) -> None:
        self.stream = stream
        self.label = label
        self.width = width
        self._last = ""
        self._drawn = False

    def line(self, record: dict[str, Any]) -> str:
        """The bar's text for ``record`` (no ``\\r``, not cut)."""
        fraction = min(max(float(record.get("progress") or 0.0), 0.0), 1.0)
        if record.get("status") == "succeeded":
            fraction = 1.0
        filled = int(round(fraction * self.width))
        bar = "#" * filled + "-" * (self.width - filled)
        message = " ".join(str(record.get("message") or record.get("error") or "").split())
        head = f"{self.label} " if self.label else ""
        return f"{head}[{bar}] {fraction:4.0%}  {record.get('status', '?')}  {message}".rstrip()

    def __call__(self, record: dict[str, Any]) -> None:
        columns = shutil.get_terminal_size((80, 24)).columns
        text = self.line(record)[: max(columns - 1, 10)]
        if text == self._last:
            return
        pad = " " * max(len(self._last) - len(text), 0)
        self.stream.write("\r" + text + pad)
        self.stream.flush()
        self._last = text
        self._drawn = True

    def close(self) -> None:
        if self._drawn:
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False


def _reporter(progress: bool | ProgressCallback | None, label: str
              ) -> tuple[Callable[[dict[str, Any]], None], Callable[[], None]]:
    """``(report(record), close())`` for ``Job.wait``'s ``progress`` argument."""
    if progress is None:
        progress = sys.stderr.isatty()
    if progress is True:
        bar = ProgressBar(sys.stderr, label)
        return bar, bar.close
    if progress is False:
        return (lambda record: None), (lambda: None)
    if callable(progress):
        callback = progress
        return (lambda record: callback(float(record.get("progress") or 0.0),
                                        str(record.get("message") or ""))), (lambda: None)
    raise TypeError("progress is None (a bar when stderr is a terminal), True, False or a "
                    "callable(progress, message)")


class Job:
    """A submitted job: ``id``, and its ``kind`` (read from the service when not known).

    ``status()`` and ``record()`` read it now; ``wait()`` polls until it has ended;
    ``result()`` fetches a succeeded job's result; ``cancel()`` stops it (or deletes it,
    with its result, once it has ended)."""

    def __init__(self, client: Client, job_id: str, kind: str | None = None,
                 record: dict[str, Any] | None = None) -> None:
        self.client = client
        self.id = job_id
        self._kind = kind
        self.last: dict[str, Any] | None = record

    def __repr__(self) -> str:
        status = self.last.get("status") if self.last else "?"
        return f"Job(id={self.id!r}, kind={self._kind!r}, status={status!r})"

    @property
    def kind(self) -> str:
        """The job's kind, e.g. ``"workspace"``."""
        if self._kind is None:
            self._kind = self.record()["kind"]
        return self._kind

    def record(self) -> dict[str, Any]:
        """The job's record now (``GET /jobs/{id}``): status, progress, message, times,
        error."""
        record = self.client._json("GET", f"/jobs/{self.id}")
        self.last = record
        self._kind = record.get("kind", self._kind)
        return record

    def status(self) -> str:
        """``queued``, ``running``, ``succeeded``, ``failed`` or ``cancelled``."""
        return str(self.record()["status"])

    def wait(self, timeout: float | None = None,
             progress: bool | ProgressCallback | None = None,
             poll: float = 0.5) -> dict[str, Any]:
        """Poll the job until it has ended; its last record.

        ``timeout``: seconds to wait at most (``TimeoutError`` after them; the job runs
        on); None waits as long as it takes. ``progress``: None draws a one-line bar on
        stderr when stderr is a terminal and is silent otherwise; True draws it anyway,
        False never; a callable is called with ``(progress, message)`` at every poll.
        ``poll``: the longest pause between polls, s (the first ones are shorter, so a
        short job is seen to end soon). A job that failed or was cancelled is returned
        too: look at ``record["status"]`` and ``record["error"]``."""
        deadline = None if timeout is None else time.monotonic() + timeout
        report, close = _reporter(progress, f"{self.kind} {self.id}")
        delay = 0.05
        try:
            while True:
                record = self.record()
                report(record)
                if record["status"] in ENDED:
                    return record
                now = time.monotonic()
                if deadline is not None and now >= deadline:
                    raise TimeoutError(f"job {self.id} still {record['status']} after "
                                       f"{timeout} s")
                pause = delay if deadline is None else min(delay, deadline - now)
                time.sleep(max(pause, 0.0))
                delay = min(delay * 1.5, poll)
        finally:
            close()

    def result(self, typed: bool = True) -> Any:
        """The result of the succeeded job (``GET /jobs/{id}/result``).

        With ``typed`` (the default), the result validated into its kind's pydantic model
        (``SleepResult``, ``MotionJobResult``, ...) when the service's package is
        importable here; the parsed JSON (a dict) otherwise, or when the result does not
        match this version's model (with a warning). ``typed=False``: always the JSON.
        ``ConflictError`` (409) while the job has not succeeded."""
        text = self.client._request("GET", f"/jobs/{self.id}/result").content
        data = json.loads(text)
        if not typed:
            return data
        model = _result_model(self.kind)
        if model is None:
            return data
        try:
            return model.model_validate_json(text)
        except ValueError as exc:  # pydantic's ValidationError is a ValueError
            warnings.warn(f"the result of job {self.id} does not match this version's "
                          f"'{self.kind}' result model, answered as JSON: {exc}",
                          stacklevel=2)
            return data

    def replay_html(self, **query: Any) -> str:
        """The succeeded job's motion as one self-contained HTML page that plays offline
        (``GET /jobs/{id}/replay.html``; ``query``: ``problem=k`` or ``arm=...``)."""
        return self.client._request("GET", f"/jobs/{self.id}/replay.html",
                                    params=query).text

    def cancel(self) -> dict[str, Any] | None:
        """Cancel the job (``DELETE /jobs/{id}``): a queued job at once, a running one
        within 2 s; its record. A job that has ended is deleted with its result: None."""
        response = self.client._request("DELETE", f"/jobs/{self.id}")
        if response.status_code == 204:
            return None
        self.last = response.json()
        return self.last


def _result_model(kind: str) -> Any:
    """The pydantic result model of job ``kind``, from the service's catalogue of kinds;
    None when the service's package is not importable here or does not know the kind.

    Imported here, on first use only: the client itself needs neither the service nor
    pydantic, and the catalogue brings the planning code with it (a few seconds)."""
    try:
        from app.jobs.catalog import KINDS
    except ImportError:
        return None
    found = KINDS.get(kind)
    return None if found is None else found.result
