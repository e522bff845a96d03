"""What the job backends share: a supervisor thread, wake-ups, stop, and cancel requests."""

from __future__ import annotations

import logging
import threading
import time

from ..store import Store

__all__ = ["SupervisedBackend"]

log = logging.getLogger(__name__)

#: Seconds to wait after a supervisor pass that failed before the next one.
RETRY_S = 0.1


class SupervisedBackend:
    """Base of the backends: ``_pass()`` (one supervisor round: start queued jobs, collect
    progress and outcomes, stop cancelled ones) runs in a loop on a daemon thread until
    ``stop``; ``_shutdown()`` releases what the backend holds."""

    name = "backend"

    def __init__(self, store: Store, workers: int) -> None:
        self.store = store
        self.workers = max(1, int(workers))
        self._cancel: set[str] = set()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = threading.Thread(target=self._loop, name=f"kinoplan-{self.name}",
                                        daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop supervising; jobs still running are left 'running' in the store, so the next
        start of the service queues them again."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10)
        self._shutdown()

    def notify(self) -> None:
        """A job was queued: look at the queue now rather than at the next poll."""
        self._wake.set()

    def cancel(self, job_id: str) -> None:
        """Stop a running job (the store already marks queued ones cancelled)."""
        with self._lock:
            self._cancel.add(job_id)
        self._wake.set()

    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _cancel_requested(self, running: set[str] | dict) -> list[str]:
        """Running jobs with a pending cancel request (requests for others are dropped)."""
        with self._lock:
            self._cancel.intersection_update(running)
            return list(self._cancel)

    def _take_cancel(self, job_id: str) -> bool:
        """Whether ``job_id`` was asked to stop; clears the request."""
        with self._lock:
            asked = job_id in self._cancel
            self._cancel.discard(job_id)
        return asked

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self._pass()
            except Exception:  # the supervisor must survive anything: log, go on
                log.exception("%s job supervisor pass failed", self.name)
                time.sleep(RETRY_S)

    def _pass(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _shutdown(self) -> None:
        """Release processes, connections or clients (after the loop has ended)."""
