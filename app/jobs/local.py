"""The embedded job backend: each running job in a worker process of its own.

A supervisor thread in the service starts up to ``workers`` processes (forked from a
forkserver that has numpy, scipy and the job kinds already imported, so a start costs
milliseconds), listens on a pipe per job for progress and the result, and writes both to the
store. One process per job is what keeps a crash contained: a job that segfaults, calls
``os._exit`` or is killed for memory fails alone, and the next job gets a fresh process.
A worker runs ``app.jobs.kinds.execute``: the params model rebuilt from the stored JSON, the
result checked against its kind's ``Result`` before it is sent back (a mismatch fails the
job, naming the field).
Cancel terminates the process (SIGTERM, then SIGKILL after a grace period), well within 2 s;
so does the job's time limit, counted from the start of its process, after which the job
fails with "time limit of N s exceeded".
"""

from __future__ import annotations

import logging
import multiprocessing
import signal
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait

from ..store import Store, StoreError
from . import catalog
from .backend import SupervisedBackend
from .kinds import JobCancelled, execute

__all__ = ["LocalBackend"]

log = logging.getLogger(__name__)

#: Seconds between supervisor passes when nothing happens.
POLL_S = 0.05
#: Seconds a cancelled job gets to exit after SIGTERM before SIGKILL.
TERMINATE_GRACE_S = 0.5
#: Least seconds between two progress writes of one job to the store.
PROGRESS_WRITE_S = 0.2


def _child_main(conn: Connection, kind: str, payload: dict) -> None:
    """Body of a worker process: run one job, send progress and the outcome down ``conn``."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C in a terminal is the service's
    last = [0.0]

    def progress(fraction: float, message: str) -> None:
        now = time.monotonic()
        if now - last[0] >= 0.05 or fraction >= 1.0:
            last[0] = now
            conn.send(("progress", min(max(float(fraction), 0.0), 1.0), str(message)[:200]))

    try:
        conn.send(("result", execute(kind, payload, progress)))
    except JobCancelled:
        conn.send(("cancelled", ""))
    except BaseException as exc:  # noqa: BLE001 - everything a job raises is its failure
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


@dataclass
class _Running:
    process: multiprocessing.process.BaseProcess
    conn: Connection
    last_write: float = 0.0
    outcome: tuple | None = None
    pending_progress: tuple[float, str] | None = None
    cancel_at: float | None = None
    time_limit_s: float | None = None
    deadline: float | None = None
    over_time: bool = False
    cancelled: bool | None = None  # asked to stop (read once, kept until the outcome is saved)


class LocalBackend(SupervisedBackend):
    """Runs queued jobs of ``store`` in up to ``workers`` processes at a time."""

    name = "local"

    def __init__(self, store: Store, workers: int) -> None:
        super().__init__(store, workers)
        self._ctx = multiprocessing.get_context("forkserver")
        # Workers fork from a server that has already imported what jobs use.
        self._ctx.set_forkserver_preload(
            ["numpy", "scipy", "scipy.optimize", "scipy.interpolate", "scipy.sparse",
             catalog.__name__]
        )
        self._running: dict[str, _Running] = {}
        # Jobs claimed (marked running) whose process could not be started yet because the
        # store failed between the claim and reading the payload: started first next pass.
        self._claimed: list = []

    def _shutdown(self) -> None:
        for job_id, run in list(self._running.items()):
            self._terminate(run)
            run.conn.close()
            self._running.pop(job_id, None)

    def _pass(self) -> None:
        self._handle_time_limits()
        self._handle_cancels()
        self._start_jobs()
        self._collect()

    def _start_jobs(self) -> None:
        while len(self._running) < self.workers and not self._stop.is_set():
            job = self._claimed.pop(0) if self._claimed else self.store.claim_next_job()
            if job is None:
                return
            try:
                payload = self.store.job_payload(job.id)
            except StoreError:
                self._claimed.insert(0, job)  # not lost: started once the store answers
                raise
            parent, child = self._ctx.Pipe(duplex=False)
            proc = self._ctx.Process(target=_child_main, args=(child, job.kind, payload),
                                     name=f"kinoplan-job-{job.id}", daemon=True)
            proc.start()
            child.close()
            self._running[job.id] = _Running(proc, parent, time_limit_s=job.time_limit_s,
                                             deadline=self._deadline(job.time_limit_s))
            log.info("job %s (%s) started in process %s", job.id, job.kind, proc.pid)

    def _collect(self) -> None:
        conns = {run.conn: job_id for job_id, run in self._running.items()}
        sentinels = {run.process.sentinel: job_id for job_id, run in self._running.items()}
        self._wake.clear()
        ready = wait(list(conns) + list(sentinels), timeout=POLL_S) if conns else []
        if not conns:
            self._wake.wait(POLL_S)
        for obj in ready:
            job_id = conns.get(obj)
            if job_id is not None:
                self._drain(job_id)
        now = time.monotonic()
        for job_id, run in list(self._running.items()):
            if run.pending_progress and now - run.last_write >= PROGRESS_WRITE_S:
                self.store.set_progress(job_id, *run.pending_progress)
                run.pending_progress, run.last_write = None, now
            if run.process.is_alive():
                continue
            self._drain(job_id)  # a result sent just before exit
            run.process.join()
            self._finish(job_id, run)

    def _drain(self, job_id: str) -> None:
        run = self._running.get(job_id)
        if run is None:
            return
        try:
            while run.conn.poll():
                msg = run.conn.recv()
                if msg[0] == "progress":
                    run.pending_progress = (msg[1], msg[2])
                else:
                    run.outcome = msg
        except (EOFError, OSError):
            pass

    def _finish(self, job_id: str, run: _Running) -> None:
        """Save the outcome of a job whose process has ended. If the store fails, the job
        stays in ``_running`` with its outcome, and the next pass saves it again."""
        if run.cancelled is None:
            run.cancelled = self._take_cancel(job_id)
        cancelled = run.cancelled
        kind, text = run.outcome if run.outcome else (None, None)
        if cancelled or kind == "cancelled":
            self.store.finish_job(job_id, "cancelled", message="cancelled")
        elif run.over_time and kind != "result":
            self._fail_over_time(job_id, run.time_limit_s or 0.0)
        elif kind == "result":
            self.store.finish_job(job_id, "succeeded", result_json=text, message="done")
        elif kind == "error":
            self.store.finish_job(job_id, "failed", error=text, message="failed")
        else:
            code = run.process.exitcode
            why = (f"killed by signal {-code}" if code is not None and code < 0
                   else f"exit code {code}")
            self.store.finish_job(
                job_id, "failed", message="worker died",
                error=f"the worker process died ({why}) before the job finished",
            )
        self._running.pop(job_id, None)
        run.conn.close()
        log.info("job %s ended (%s)", job_id, kind or "died")

    def _handle_cancels(self) -> None:
        for job_id in self._cancel_requested(set(self._running)):
            self._stop_process(self._running[job_id])

    def _handle_time_limits(self) -> None:
        """Stop the processes of jobs past their time limit (they fail when they exit)."""
        overdue = self._overdue({job_id: run.deadline for job_id, run in self._running.items()})
        for job_id in overdue:
            run = self._running[job_id]
            if not run.over_time:
                log.info("job %s reached its time limit of %g s", job_id, run.time_limit_s)
            run.over_time = True
            self._stop_process(run)

    @staticmethod
    def _stop_process(run: _Running) -> None:
        """SIGTERM the job's process, SIGKILL it once the grace period has passed."""
        if run.cancel_at is None:
            run.cancel_at = time.monotonic()
            run.process.terminate()
        elif time.monotonic() - run.cancel_at > TERMINATE_GRACE_S:
            run.process.kill()

    @staticmethod
    def _terminate(run: _Running) -> None:
        if run.process.is_alive():
            run.process.terminate()
            run.process.join(TERMINATE_GRACE_S)
            if run.process.is_alive():
                run.process.kill()
                run.process.join(1.0)
