"""The embedded job backend: each step of a running job in a worker process of its own.

A job is a graph of steps (``app.jobs.graph``: one step for most kinds; the parts and merges
of a big workspace, a motion batch, tracking statistics, ... for the kinds that divide). A
supervisor thread in the service runs up to ``workers`` steps at a time, of one job or of
several (the oldest running job's ready steps first, then the next queued job), each in a
process forked from a forkserver that has numpy, scipy and the job kinds already imported (a
start costs milliseconds). It listens on a pipe per step for progress and the step's value,
keeps the values later steps need, and writes the job's progress (the steps' own, weighted)
and its result to the store. One process per step keeps a crash contained: a step that
segfaults, calls ``os._exit`` or is killed for memory fails its job alone. A step's process
rebuilds the params model from the stored JSON; the last step's value is checked against the
kind's ``Result`` before it is sent back (a mismatch fails the job, naming the field).
Cancel terminates the job's processes (SIGTERM, then SIGKILL after a grace period), well
within 2 s; so does the job's time limit, counted from the start of its first step, after
which the job fails with "time limit of N s exceeded".
"""

from __future__ import annotations

import logging
import multiprocessing
import signal
import time
from dataclasses import dataclass, field
from multiprocessing.connection import Connection, wait
from typing import Any

from ..lifetime import forkserver_context
from ..store import JobRecord, Store
from . import catalog
from .backend import SupervisedBackend
from .graph import Step, Tracker, refs_of, resolve, throttled
from .kinds import JobCancelled, load_job

__all__ = ["LocalBackend"]

log = logging.getLogger(__name__)

#: Seconds between supervisor passes when nothing happens.
POLL_S = 0.05
#: Least seconds between two progress messages of a step's process.
PROGRESS_EVERY_S = 0.05
#: Seconds a cancelled job gets to exit after SIGTERM before SIGKILL.
TERMINATE_GRACE_S = 0.5


def _child_main(conn: Connection, kind: str, payload: dict, fn: Any, args: tuple,
                final: bool) -> None:
    """Body of a worker process: run one step, send progress and its value down ``conn``."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C in a terminal is the service's
    progress = throttled(lambda f, m: conn.send(("progress", f, m)), PROGRESS_EVERY_S)
    try:
        job_kind, params = load_job(kind, payload)
        value = fn(params, *args, progress)
        conn.send(("value", job_kind.result_json(value) if final else value))
    except JobCancelled:
        conn.send(("cancelled", ""))
    except BaseException as exc:  # noqa: BLE001 - everything a step raises is its failure
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


@dataclass
class _Running:
    """One step's process."""

    job_id: str
    index: int
    process: multiprocessing.process.BaseProcess
    conn: Connection
    outcome: tuple | None = None
    cancel_at: float | None = None


@dataclass
class _Job:
    """A running job: its steps, the values later steps still need, its processes."""

    record: JobRecord
    payload: dict
    steps: list[Step]
    tracker: Tracker
    deadline: float | None
    #: Steps not started yet, in order, with the steps each waits for.
    waiting: dict[int, set[int]]
    #: Values of finished steps that a later step still needs, and how many still do.
    values: dict[int, Any] = field(default_factory=dict)
    users: dict[int, int] = field(default_factory=dict)
    running: dict[int, _Running] = field(default_factory=dict)
    over_time: bool = False
    cancelled: bool | None = None  # asked to stop (read once, kept until the outcome is saved)
    #: The outcome once decided: ("succeeded", result) / ("failed", error) / ("cancelled",).
    ending: tuple | None = None

    @property
    def id(self) -> str:
        return self.record.id

    def ready(self) -> list[int]:
        return [i for i, deps in self.waiting.items() if not deps]


class LocalBackend(SupervisedBackend):
    """Runs the steps of queued jobs of ``store`` in up to ``workers`` processes at a time."""

    name = "local"

    def __init__(self, store: Store, workers: int) -> None:
        super().__init__(store, workers)
        # Workers fork from a server that has already imported what jobs use; they and the
        # server die with the service, even a killed one (app.lifetime).
        # "__main__": a child does not run the main script again (a service embedded in a
        # user's script would otherwise re-run it before every step).
        self._ctx = forkserver_context(
            ["__main__", "numpy", "scipy", "scipy.optimize", "scipy.interpolate",
             "scipy.sparse", catalog.__name__, "app.jobs.warm_kernels"]
        )
        self._jobs: dict[str, _Job] = {}

    def _procs(self) -> list[_Running]:
        return [run for job in self._jobs.values() for run in job.running.values()]

    def _shutdown(self) -> None:
        for run in self._procs():
            self._terminate(run)
            run.conn.close()
        self._jobs.clear()

    def _pass(self) -> None:
        self._handle_time_limits()
        self._handle_cancels()
        self._start_steps()
        self._collect()
        self._settle()

    # ---- starting ------------------------------------------------------------------
    def _start_steps(self) -> None:
        """Fill free process slots: ready steps of running jobs (oldest first), then the
        steps of newly claimed jobs."""
        while not self._stop.is_set():
            free = self.workers - len(self._procs())
            if free <= 0:
                return
            job = next((j for j in self._jobs.values() if j.ending is None and j.ready()),
                       None)
            if job is None:
                job = self._claim()
                if job is None:
                    return
                if not job.ready():
                    continue
            for index in job.ready()[:free]:
                self._spawn(job, index)

    def _claim(self) -> _Job | None:
        """The next queued job, marked running, with its steps planned (a job whose steps
        cannot be planned fails, and the next is taken)."""
        claimed = self._claim_planned()
        return None if claimed is None else self._add(*claimed)

    def _add(self, record: JobRecord, payload: dict, steps: list[Step]) -> _Job:
        users: dict[int, int] = {}
        waiting = {}
        for i, step in enumerate(steps):
            deps = refs_of(step)
            waiting[i] = set(deps)
            for j in deps:
                users[j] = users.get(j, 0) + 1
        job = _Job(record, payload, steps, Tracker(steps), self._deadline(record.time_limit_s),
                   waiting, users=users)
        self._jobs[record.id] = job
        return job

    def _spawn(self, job: _Job, index: int) -> None:
        step = job.steps[index]
        job.waiting.pop(index)
        args = resolve(step.args, job.values.__getitem__)
        final = index == len(job.steps) - 1
        parent, child = self._ctx.Pipe(duplex=False)
        proc = self._ctx.Process(
            target=_child_main, args=(child, job.record.kind, job.payload, step.fn, args, final),
            name=f"kinoplan-job-{job.id}-{index}", daemon=True)
        proc.start()
        child.close()
        job.running[index] = _Running(job.id, index, proc, parent)
        log.info("job %s (%s) step %d of %d started in process %s", job.id, job.record.kind,
                 index + 1, len(job.steps), proc.pid)

    # ---- collecting ----------------------------------------------------------------
    def _collect(self) -> None:
        runs = self._procs()
        conns = {run.conn: run for run in runs}
        self._wake.clear()
        if runs:
            ready = wait(list(conns) + [run.process.sentinel for run in runs], timeout=POLL_S)
        else:
            ready = []
            self._wake.wait(POLL_S)
        for obj in ready:
            run = conns.get(obj)
            if run is not None:
                self._drain(run)
        for run in runs:
            if run.process.is_alive():
                continue
            self._drain(run)  # a value sent just before exit
            run.process.join()
            self._step_ended(self._jobs[run.job_id], run)

    def _drain(self, run: _Running) -> None:
        job = self._jobs.get(run.job_id)
        try:
            while run.conn.poll():
                msg = run.conn.recv()
                if msg[0] == "progress":
                    if job is not None:
                        job.tracker.report(run.index, msg[1], msg[2])
                else:
                    run.outcome = msg
        except (EOFError, OSError):
            pass

    def _step_ended(self, job: _Job, run: _Running) -> None:
        """A step's process has exited: keep its value, or decide the job's outcome."""
        job.running.pop(run.index, None)
        run.conn.close()
        kind, value = run.outcome if run.outcome else (None, None)
        if job.ending is not None:
            return
        if kind == "value":
            job.tracker.update(run.index, 1.0)
            job.tracker.dirty = True
            if run.index == len(job.steps) - 1:
                job.ending = ("succeeded", value)
                return
            if job.users.get(run.index):
                job.values[run.index] = value
            for deps in job.waiting.values():
                deps.discard(run.index)
            for j in refs_of(job.steps[run.index]):
                job.users[j] -= 1
                if job.users[j] == 0:
                    job.values.pop(j, None)
            return
        if kind == "cancelled":
            job.ending = ("cancelled",)
        elif kind == "error":
            job.ending = ("failed", value)
        elif run.cancel_at is None:
            code = run.process.exitcode
            why = (f"killed by signal {-code}" if code is not None and code < 0
                   else f"exit code {code}")
            job.ending = ("died", f"the worker process died ({why}) before the job finished")
        else:
            job.ending = ("stopped",)
        for other in job.running.values():  # the job has failed: its other steps stop
            self._stop_process(other)

    def _settle(self) -> None:
        """Write progress, and the outcome of each job whose processes have all ended. If
        the store fails, the job stays with its outcome and the next pass saves it again."""
        for job in list(self._jobs.values()):
            if job.ending is None:
                self._save_progress(job.id, job.tracker)
            if job.ending is None or job.running:
                continue
            self._finish(job)

    def _finish(self, job: _Job) -> None:
        if job.cancelled is None:
            job.cancelled = self._take_cancel(job.id)
        what = job.ending[0]
        if job.cancelled or what == "cancelled":
            self.store.finish_job(job.id, "cancelled", message="cancelled")
        elif job.over_time and what != "succeeded":
            self._fail_over_time(job.id, job.record.time_limit_s or 0.0)
        elif what == "succeeded":
            self.store.finish_job(job.id, "succeeded", result_json=job.ending[1],
                                  message="done")
        elif what == "failed":
            self.store.finish_job(job.id, "failed", error=job.ending[1], message="failed")
        else:
            self.store.finish_job(job.id, "failed", message="worker died",
                                  error=job.ending[1] if what == "died" else
                                  "the job's worker process was stopped")
        self._jobs.pop(job.id, None)
        log.info("job %s ended (%s)", job.id, what)

    # ---- stopping ------------------------------------------------------------------
    def _stop_job(self, job: _Job) -> None:
        """Stop every process of the job; it ends once they have exited."""
        if job.ending is None:
            job.ending = ("stopped",)
        for run in job.running.values():
            self._stop_process(run)

    def _handle_cancels(self) -> None:
        """Stop cancelled jobs, and the other steps of jobs that have failed (SIGKILL once
        a process outlives its grace period)."""
        for job_id in self._cancel_requested(set(self._jobs)):
            self._stop_job(self._jobs[job_id])
        for job in self._jobs.values():
            if job.ending is not None and job.running:
                self._stop_job(job)

    def _handle_time_limits(self) -> None:
        """Stop the processes of jobs past their time limit (they fail when they exit)."""
        overdue = self._overdue({job_id: job.deadline for job_id, job in self._jobs.items()
                                 if job.ending is None or job.running})
        for job_id in overdue:
            job = self._jobs[job_id]
            if not job.over_time:
                log.info("job %s reached its time limit of %g s", job_id,
                         job.record.time_limit_s)
            job.over_time = True
            self._stop_job(job)

    @staticmethod
    def _stop_process(run: _Running) -> None:
        """SIGTERM the step's process, SIGKILL it once the grace period has passed."""
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
