"""Scale-out: run the same job functions on a Dask distributed cluster.

``--jobs-backend dask://HOST:PORT`` connects to a running scheduler. The service still
keeps every job in its own store (queue order, records, results) and hands the cluster as
many jobs at a time as it has worker threads, so the cluster's size sets the throughput.
A job reports progress through a Dask
``Variable`` the supervisor polls, and checks a cancel ``Event`` whenever it reports
progress, so a running job stops within one progress step of a cancel (our kinds report at
least every second); the future is cancelled as well. A job past its time limit (counted
from its submission to the cluster) is failed at once with "time limit of N s exceeded" and
stopped the same way as a cancelled one.

Dask is an optional extra (``pip install ".[dask]"``); the embedded default never imports it.
"""

from __future__ import annotations

import logging
import time

from ..store import Store
from . import catalog  # noqa: F401 - a worker unpickling run_on_cluster gets every kind
from .backend import SupervisedBackend
from .kinds import JobCancelled, execute

__all__ = ["DaskBackend", "run_on_cluster"]

log = logging.getLogger(__name__)

POLL_S = 0.1


def _names(job_id: str) -> tuple[str, str]:
    return f"kinoplan-progress-{job_id}", f"kinoplan-cancel-{job_id}"


def run_on_cluster(job_id: str, kind: str, payload: dict) -> str:
    """What a Dask worker runs: one job, with progress and cooperative cancel."""
    from distributed import Event, Variable

    progress_name, cancel_name = _names(job_id)
    progress_var = Variable(progress_name)
    cancel = Event(cancel_name)
    last = [0.0]

    def progress(fraction: float, message: str) -> None:
        now = time.monotonic()
        if now - last[0] < 0.2 and fraction < 1.0:
            return
        last[0] = now
        if cancel.is_set():
            raise JobCancelled()
        progress_var.set([min(max(float(fraction), 0.0), 1.0), str(message)[:200]])

    return execute(kind, payload, progress)


class DaskBackend(SupervisedBackend):
    """Hands queued jobs of ``store`` to the Dask scheduler at ``address``."""

    name = "dask"

    def __init__(self, store: Store, address: str, workers: int) -> None:
        try:
            from distributed import Client
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise RuntimeError(
                "the dask backend needs the 'dask' extra: pip install '.[dask]'"
            ) from exc
        super().__init__(store, workers)
        self.address = address
        self.client = Client(address, timeout="10s", set_as_default=False)
        self._futures: dict[str, object] = {}
        self._limits: dict[str, tuple[float | None, float | None]] = {}  # (limit, deadline)

    def capacity(self) -> int:
        """Jobs to keep in flight: the cluster's worker threads (at least ``workers``)."""
        try:
            threads = sum(self.client.nthreads().values())
        except Exception:  # noqa: BLE001 - scheduler briefly unreachable
            threads = 0
        return max(self.workers, threads)

    def _shutdown(self) -> None:
        for job_id, fut in list(self._futures.items()):
            self._signal_cancel(job_id)
            fut.cancel()
        self.client.close()

    def _signal_cancel(self, job_id: str) -> None:
        from distributed import Event

        Event(_names(job_id)[1], client=self.client).set()

    def _pass(self) -> None:
        self._handle_time_limits()
        self._handle_cancels()
        self._start_jobs()
        self._collect()
        self._wake.wait(POLL_S)
        self._wake.clear()

    def _start_jobs(self) -> None:
        cap = self.capacity()
        while len(self._futures) < cap and not self._stop.is_set():
            job = self.store.claim_next_job()
            if job is None:
                return
            payload = self.store.job_payload(job.id)
            fut = self.client.submit(run_on_cluster, job.id, job.kind, payload,
                                     key=f"kinoplan-job-{job.id}-{job.attempts}", pure=False)
            self._futures[job.id] = fut
            self._limits[job.id] = (job.time_limit_s, self._deadline(job.time_limit_s))

    def _collect(self) -> None:
        from distributed import Variable

        for job_id, fut in list(self._futures.items()):
            status = fut.status
            if status == "pending":
                got = None
                try:
                    got = Variable(_names(job_id)[0], client=self.client).get(timeout=0.01)
                except Exception:  # noqa: BLE001 - no progress reported yet
                    pass
                if got:
                    self.store.set_progress(job_id, float(got[0]), str(got[1]))
                continue
            self._futures.pop(job_id)
            self._limits.pop(job_id, None)
            cancelled = self._take_cancel(job_id)
            if status == "finished":
                self.store.finish_job(job_id, "succeeded", result_json=fut.result(),
                                      message="done")
            elif cancelled or status == "cancelled":
                self.store.finish_job(job_id, "cancelled", message="cancelled")
            else:
                exc = fut.exception()
                if isinstance(exc, JobCancelled):
                    self.store.finish_job(job_id, "cancelled", message="cancelled")
                else:
                    self.store.finish_job(job_id, "failed", message="failed",
                                          error=f"{type(exc).__name__}: {exc}")
            self._forget(job_id)

    def _forget(self, job_id: str) -> None:
        """Drop the job's progress variable from the scheduler."""
        from distributed import Variable

        for name in _names(job_id):
            try:
                Variable(name, client=self.client).delete()
            except Exception:  # noqa: BLE001 - Events have no delete; best effort
                pass

    def _handle_time_limits(self) -> None:
        """Fail the jobs past their time limit now; stop them as a cancel does."""
        overdue = self._overdue({job_id: deadline
                                 for job_id, (_, deadline) in self._limits.items()})
        for job_id in overdue:
            limit, _ = self._limits.pop(job_id)
            fut = self._futures.pop(job_id, None)
            self._signal_cancel(job_id)
            if fut is not None:
                fut.cancel()
            self._take_cancel(job_id)
            self._fail_over_time(job_id, limit or 0.0)
            self._forget(job_id)

    def _handle_cancels(self) -> None:
        for job_id in self._cancel_requested(set(self._futures)):
            self._signal_cancel(job_id)
            self._futures[job_id].cancel()
