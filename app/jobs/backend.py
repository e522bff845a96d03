"""What the job backends share: a supervisor thread, wake-ups, stop, and cancel requests."""

from __future__ import annotations

import logging
import threading
import time

from ..store import Store, StoreError

__all__ = ["SupervisedBackend"]

log = logging.getLogger(__name__)

#: Seconds to wait after a supervisor pass that failed before the next one; the wait doubles
#: with each further failure up to ``RETRY_MAX_S`` and starts again after a pass succeeds.
RETRY_S = 0.1
#: Longest wait between two failing supervisor passes.
RETRY_MAX_S = 5.0
#: Distinct error messages logged in one spell of failing passes.
MAX_LOGGED_ERRORS = 10
#: Least seconds between two progress writes of one job to the store.
PROGRESS_WRITE_S = 0.2


class SupervisedBackend:
    """Base of the backends: ``_pass()`` (one supervisor round: start queued jobs, collect
    progress and outcomes, stop cancelled ones) runs in a loop on a daemon thread until
    ``stop``; ``_shutdown()`` releases what the backend holds."""

    name = "backend"
    #: Why supervisor passes are failing ("Type: message"), None while they succeed.
    failing: str | None = None

    def __init__(self, store: Store, workers: int) -> None:
        self.store = store
        self.workers = max(1, int(workers))
        # Jobs claimed (marked running) whose payload the store failed to give: taken first
        # at the next pass, so none is left running without a worker.
        self._claimed: list = []
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

    def parallelism(self) -> int:
        """Job steps run at once."""
        return self.workers

    def unavailable(self) -> str | None:
        """Why jobs cannot be taken now (a cluster out of reach); None: they can."""
        return None

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
        """Run passes until ``stop``. A failing pass (say the store is unusable) is retried
        with exponential back-off; the first failure is logged with its traceback, each new
        message of the same spell in one line, and the recovery once."""
        delay, since, logged = RETRY_S, 0.0, set()
        while not self._stop.is_set():
            try:
                self._pass()
            except Exception as exc:  # the supervisor must survive anything: log, go on
                message = f"{type(exc).__name__}: {exc}"
                if self.failing is None:
                    since, logged = time.monotonic(), {message}
                    log.exception("%s job supervisor pass failed; retrying with back-off",
                                  self.name)
                elif message not in logged and len(logged) < MAX_LOGGED_ERRORS:
                    logged.add(message)
                    log.warning("%s job supervisor pass still failing: %s", self.name, message)
                self.failing = message
                # A stop, or a new job (so the store takes writes again), ends the wait early.
                self._wake.wait(delay)
                self._wake.clear()
                delay = min(delay * 2, RETRY_MAX_S)
                continue
            if self.failing is not None:
                log.warning("%s job supervisor recovered after %.1f s of failing passes",
                            self.name, time.monotonic() - since)
                self.failing, delay = None, RETRY_S

    def _pass(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _shutdown(self) -> None:
        """Release processes, connections or clients (after the loop has ended)."""

    def _save_progress(self, job_id: str, tracker) -> None:
        """Write a job's progress (``app.jobs.graph.Tracker``) when it has news, at most
        every ``PROGRESS_WRITE_S``."""
        now = time.monotonic()
        if tracker.dirty and now - tracker.last_write >= PROGRESS_WRITE_S:
            self.store.set_progress(job_id, tracker.fraction(), tracker.message[:200])
            tracker.dirty, tracker.last_write = False, now

    def _claim_planned(self) -> tuple | None:
        """The next queued job, marked running: ``(record, payload, steps)``; None when none
        is queued. A job whose steps cannot be planned fails, and the next is taken; a store
        failure after the claim keeps the job for the next call and raises."""
        from .kinds import JobPayload, get_kind

        while True:
            record = self._claimed.pop(0) if self._claimed else self.store.claim_next_job()
            if record is None:
                return None
            try:
                payload = self.store.job_payload(record.id)
            except StoreError:
                self._claimed.insert(0, record)
                raise
            except KeyError:  # payloads go only with the job's end; never run one without
                self.store.finish_job(record.id, "failed", message="failed",
                                      error="the job's payload is missing from the store")
                continue
            try:
                kind = get_kind(record.kind)
                steps = kind.steps(kind.load_params(JobPayload.from_stored(payload).params))
            except Exception as exc:  # noqa: BLE001 - a job that cannot be planned fails
                self.store.finish_job(record.id, "failed", message="failed",
                                      error=f"{type(exc).__name__}: {exc}")
                continue
            return record, payload, steps

    # ---- time limits ------------------------------------------------------------------
    @staticmethod
    def _deadline(time_limit_s: float | None) -> float | None:
        """When (``time.monotonic()``) a job with this limit, started now, must have ended;
        None for a job without a limit."""
        return None if time_limit_s is None else time.monotonic() + float(time_limit_s)

    @staticmethod
    def _overdue(deadlines: dict[str, float | None]) -> list[str]:
        """The jobs among ``{job id: deadline}`` whose deadline has passed."""
        now = time.monotonic()
        return [job_id for job_id, at in deadlines.items() if at is not None and now >= at]

    def _fail_over_time(self, job_id: str, time_limit_s: float) -> None:
        """End a job stopped at its time limit: failed, the error saying so."""
        from .caps import time_limit_message

        self.store.finish_job(job_id, "failed", message="time limit exceeded",
                              error=time_limit_message(time_limit_s))
        log.info("job %s stopped at its time limit of %g s", job_id, time_limit_s)
