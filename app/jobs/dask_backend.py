"""Scale-out: run jobs on a Dask distributed cluster, spread over all its workers.

``--jobs-backend dask://HOST:PORT`` (or ``tcp://`` / ``tls://`` with Dask's TLS settings)
names a scheduler. The service keeps every job in its own store (queue order, records,
results) and hands the cluster a job's steps (``app.jobs.graph``) as tasks, so the parts of one
big job run on every worker at once; the last step's value is the job's result. A job is
claimed from the queue while the cluster has fewer unfinished steps than worker threads.

Each task runs its step in a child process of the Dask worker (``app.jobs.runner``); it
reports its start and progress on the service's Dask ``Queue`` (one for all its jobs, drained
once per supervisor pass), and checks the job's cancel ``Event`` every 0.2 s: a cancel, or
the job's time limit, kills the child, so the worker's CPU is free at once whatever the step
is doing.

Faults: the service starts without a reachable scheduler and connects when one appears; while
none is reachable, submissions are refused (``unavailable``: 503) and ``/health`` says so, while
the synchronous endpoints work on. Jobs running when the connection is lost stay ``running``
and are handed to the cluster again once it is back (``attempts`` counts each start); after
``deadline_s`` without a scheduler, jobs still running or queued fail, naming the scheduler.
A task whose worker dies is re-run by the scheduler on another worker (counted in
``attempts`` too). A job is never cancelled unless a client asked.

Dask is an optional extra (``pip install ".[dask]"``); the embedded default never imports it.
"""

from __future__ import annotations

import logging
import threading
import time
import uuid
from dataclasses import dataclass, field
from typing import Any

from ..store import Store
from . import catalog  # noqa: F401 - a worker unpickling run_step gets every kind
from .backend import SupervisedBackend
from .graph import Step, Tracker, resolve
from .runner import StepCancelled, StepFailed, give_back, take_runner

__all__ = ["DaskBackend", "run_step", "DEFAULT_DEADLINE_S"]

log = logging.getLogger(__name__)

#: Seconds between supervisor passes.
POLL_S = 0.1
#: Seconds between two attempts to reach a lost scheduler.
RECONNECT_EVERY_S = 1.0
#: Seconds one connection attempt may take.
CONNECT_TIMEOUT_S = 3.0
#: Seconds without a scheduler after which running and queued jobs fail (``--cluster-
#: deadline-s``).
DEFAULT_DEADLINE_S = 600.0
#: Seconds between two checks of a running task for its job's cancel event.
CANCEL_CHECK_S = 0.2


def _task_name(step: Step) -> str:
    """The step's function as words of a task key: ``workspace_bounds_step`` ->
    ``workspace-bounds-step``."""
    return "-".join(w for w in step.fn.__name__.split("_") if w) or "step"


def _cancel_name(job_key: str) -> str:
    """The job's cancel event on the scheduler."""
    return f"kinoplan-cancel-{job_key}"


class SchedulerLost(RuntimeError):
    """A step stopped because its worker could no longer reach the scheduler (nobody asked
    for a cancel): the job is handed over again."""


def _payload(payload: dict) -> dict:
    """A task holding the job's payload, which every step of the job depends on (so it
    travels once to each worker that runs a step)."""
    return payload


_WORKER_CLIENT = threading.Lock()


def worker_client() -> Any:
    """The worker's client, made by one thread at a time: a worker's threads share one client,
    made on first use, and two steps starting at once on a fresh worker would both make it
    (Dask's worker does not guard that) -- one of them then fails on the half-made
    connection."""
    from distributed import get_client

    with _WORKER_CLIENT:
        return get_client()


def run_step(queue_name: str, job_key: str, index: int, kind: str, payload: dict, fn: Any,
             args: tuple, final: bool) -> Any:
    """What a Dask worker runs: one step of a job in a child process, with its start and
    progress (as often as the runner sends it) put on the service's queue ``queue_name`` and
    the job's cancel event watched."""
    from distributed import Queue

    worker_client()
    queue = Queue(queue_name)
    try:
        queue.put(("start", job_key, index))
        return _run_step(queue, job_key, index, kind, payload, fn, args, final)
    finally:
        try:
            queue.close()  # this task's hold on the queue; the service keeps its own
        except Exception:  # noqa: BLE001 - the scheduler is gone, and the queue with it
            pass


def _run_step(queue: Any, job_key: str, index: int, kind: str, payload: dict, fn: Any,
              args: tuple, final: bool) -> Any:
    from distributed import Event

    cancel = Event(_cancel_name(job_key))
    checked, lost = [time.monotonic()], [False]

    def progress(fraction: float, message: str) -> None:
        queue.put(("progress", job_key, index, float(fraction), message))

    def should_stop() -> bool:
        now = time.monotonic()
        if now - checked[0] < CANCEL_CHECK_S:
            return False
        checked[0] = now
        try:
            return cancel.is_set()
        except Exception:  # noqa: BLE001 - the scheduler is gone: stop, nobody waits
            lost[0] = True
            return True

    if cancel.is_set():
        raise StepCancelled("cancelled")
    runner = take_runner()
    try:
        value = runner.run(job_key, kind, payload, fn, args, final, progress, should_stop)
    except StepCancelled:
        runner.kill()
        if lost[0]:
            raise SchedulerLost("the step's worker lost its scheduler") from None
        raise
    except BaseException:
        runner.kill()
        raise
    give_back(runner)
    return value


@dataclass
class _Job:
    """A job handed to the cluster: its steps, their futures and what they reported."""

    id: str
    kind: str
    payload: dict
    steps: list[Step]
    time_limit_s: float | None
    deadline: float | None
    generation: int = 0
    futures: list = field(default_factory=list)
    payload_future: Any = None
    tracker: Tracker | None = None
    starts: list[int] = field(default_factory=list)

    @property
    def key(self) -> str:
        return f"{self.id}-{self.generation}"

    def unfinished(self) -> int:
        return sum(1 for f in self.futures if f.status != "finished")


class DaskBackend(SupervisedBackend):
    """Hands queued jobs of ``store`` to the Dask scheduler at ``address``."""

    name = "dask"

    def __init__(self, store: Store, address: str, workers: int,
                 deadline_s: float = DEFAULT_DEADLINE_S) -> None:
        try:
            import distributed  # noqa: F401
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise RuntimeError(
                "the dask backend needs the 'dask' extra: pip install '.[dask]'"
            ) from exc
        super().__init__(store, workers)
        self.address = address
        self.deadline_s = float(deadline_s)
        self.client: Any = None
        #: The queue the tasks of this service's jobs report on (a handle per connection).
        self._queue_name = f"kinoplan-msgs-{uuid.uuid4().hex[:16]}"
        self._queue: Any = None
        self._jobs: dict[str, _Job] = {}
        #: Since when no scheduler is connected (None while one is).
        self._down_since: float | None = time.monotonic()
        self._next_try = 0.0
        self._warned = False
        #: Lost clients still trying to reconnect on their own (closed by Dask, then dropped).
        self._retired: list = []
        self._threads = 0

    # ---- state the service reads --------------------------------------------------------
    def unavailable(self) -> str | None:
        """Why jobs cannot be taken now (None: they can)."""
        if self.connected():
            return None
        since = self._down_since
        how_long = "" if since is None else f" (for {time.monotonic() - since:.0f} s)"
        return (f"the Dask scheduler at {self.address} is unreachable{how_long}; jobs are "
                "taken again once it is back, the synchronous endpoints work meanwhile")

    def connected(self) -> bool:
        client = self.client
        return client is not None and client.status == "running"

    def parallelism(self) -> int:
        """The cluster's worker threads (0 while no scheduler is connected)."""
        return self._threads if self.connected() else 0

    def capacity(self) -> int:
        """Steps to keep on the cluster: its worker threads (at least ``workers``)."""
        return max(self.workers, self._threads)

    def start(self) -> None:
        """Connect first (at most ``CONNECT_TIMEOUT_S``), so that a service whose scheduler
        is up takes jobs from its first request; then supervise (and keep trying, if the
        scheduler did not answer)."""
        self._connect()
        super().start()

    # ---- the connection -------------------------------------------------------------
    def _connect(self) -> bool:
        """Try to reach the scheduler (at most every ``RECONNECT_EVERY_S``)."""
        now = time.monotonic()
        if now < self._next_try:
            return False
        self._next_try = now + RECONNECT_EVERY_S
        from distributed import Client, Queue

        try:
            client = Client(self.address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
            queue = Queue(self._queue_name, client=client)
        except Exception as exc:  # noqa: BLE001 - unreachable, refused, TLS, ...
            if not self._warned:
                log.warning("the Dask scheduler at %s is unreachable (%s: %s); trying again "
                            "every %g s", self.address, type(exc).__name__, exc,
                            RECONNECT_EVERY_S)
                self._warned = True
            return False
        down = time.monotonic() - (self._down_since or now)
        self.client, self._queue, self._down_since, self._warned = client, queue, None, False
        log.warning("connected to the Dask scheduler at %s%s", self.address,
                    f" after {down:.1f} s without it" if self._jobs else "")
        for job in list(self._jobs.values()):
            self._submit(job, again=True)
        return True

    def _lost(self) -> None:
        """The connection is gone: drop the client; running jobs wait for the next one."""
        client, self.client, self._queue = self.client, None, None
        self._down_since = time.monotonic()
        self._next_try = 0.0
        log.warning("lost the Dask scheduler at %s; %d running job(s) wait for it",
                    self.address, len(self._jobs))
        for job in self._jobs.values():
            job.futures, job.payload_future = [], None
            job.tracker = Tracker(job.steps)  # its work is lost: it starts over
            job.tracker.message, job.tracker.dirty = "waiting for the Dask scheduler", True
        if client.status == "connecting":
            # Its own reconnection gives up after CONNECT_TIMEOUT_S and closes it; closing
            # it now would only interrupt that with tracebacks in the log.
            self._retired.append(client)
        else:
            threading.Thread(target=_close_quietly, args=(client,), daemon=True,
                             name="kinoplan-dask-close").start()
        self._retired = [c for c in self._retired if c.status != "closed"]

    def _shutdown(self) -> None:
        for client in self._retired:
            _close_quietly(client)
        if self.client is not None:
            for job in self._jobs.values():
                self._signal_cancel(job)
            try:
                self._queue.close()
            except Exception:  # noqa: BLE001 - best effort; the scheduler may be gone
                pass
            _close_quietly(self.client)
            self.client = None

    # ---- supervisor pass -----------------------------------------------------------
    def _pass(self) -> None:
        if self.client is not None and self.client.status != "running":
            self._lost()
        if self.client is None:
            # Cancels and time limits apply while the cluster is away too (nothing of the
            # job runs then: its record ends at once).
            self._handle_time_limits()
            self._handle_cancels()
            if not self._connect():
                self._outage()
        if self.client is not None:
            try:
                self._threads = sum(self.client.nthreads().values())
            except Exception:  # noqa: BLE001 - lost in between: the next pass sees it
                pass
            self._handle_time_limits()
            self._handle_cancels()
            self._start_jobs()
            self._collect()
        self._write_progress()
        self._wake.wait(POLL_S)
        self._wake.clear()

    def _outage(self) -> None:
        """Past the deadline without a scheduler: fail what waits for it."""
        down = time.monotonic() - (self._down_since or time.monotonic())
        if down < self.deadline_s:
            return
        why = (f"the Dask scheduler at {self.address} was unreachable for {down:.0f} s "
               f"(deadline {self.deadline_s:g} s)")
        for job_id in list(self._jobs):
            self._jobs.pop(job_id)
            self._take_cancel(job_id)
            self.store.finish_job(job_id, "failed", message="cluster unreachable", error=why)
        while (job := self.store.claim_next_job()) is not None:
            self.store.finish_job(job.id, "failed", message="cluster unreachable", error=why)

    def _start_jobs(self) -> None:
        while not self._stop.is_set():
            busy = sum(job.unfinished() for job in self._jobs.values())
            if busy >= self.capacity():
                return
            claimed = self._claim_planned()
            if claimed is None:
                return
            record, payload, steps = claimed
            job = _Job(record.id, record.kind, payload, steps, record.time_limit_s,
                       self._deadline(record.time_limit_s))
            self._jobs[job.id] = job
            self._submit(job)

    def _submit(self, job: _Job, again: bool = False) -> None:
        """Hand the job's steps to the cluster (``again``: after the cluster was lost)."""
        if again:
            job.generation += 1
            self.store.count_attempt(job.id, "re-submitted after the cluster was lost")
            job.deadline = self._deadline(job.time_limit_s)  # a new attempt's time limit
        client = self.client
        key = job.key
        # Task keys begin with what the task does, in words of letters (Dask keeps its
        # estimate of a task's duration by the key's leading words, dask.utils.key_split):
        # a step estimated as short as the payload would stay on the worker holding the
        # payload instead of spreading.
        job.payload_future = client.submit(_payload, job.payload, key=f"kinoplan-payload-{key}",
                                           pure=False)
        last = len(job.steps) - 1
        futures: list = []
        # Steps dealt round the workers (a loose hint: any worker may still take one). On a
        # fresh cluster the scheduler knows no step's duration and put the first steps on the
        # worker holding the payload, one after the other, while the others stood idle.
        workers = self._worker_addresses(client)
        for i, step in enumerate(job.steps):
            args = resolve(step.args, futures)
            where = {"workers": [workers[i % len(workers)]], "allow_other_workers": True} \
                if workers else {}
            futures.append(client.submit(
                run_step, self._queue_name, key, i, job.kind, job.payload_future, step.fn,
                args, i == last,
                key=f"kinoplan-{_task_name(step)}-{key}-{i}", pure=False, retries=0, **where))
        job.futures = futures
        job.tracker = Tracker(job.steps)
        job.starts = [0] * len(job.steps)

    @staticmethod
    def _worker_addresses(client: Any) -> list[str]:
        """The cluster's workers as the client last heard of them (no round trip)."""
        try:
            return sorted(client.scheduler_info().get("workers", {}))
        except Exception:  # noqa: BLE001 - no hint then: the scheduler places the steps
            return []

    def _collect(self) -> None:
        try:
            msgs = self._queue.get(batch=True)
        except Exception:  # noqa: BLE001 - the scheduler just left: the next pass sees it
            msgs = []
        by_key = {job.key: job for job in self._jobs.values() if job.futures}
        for msg in msgs or ():
            job = by_key.get(msg[1])  # None: a job that has ended, or an earlier attempt's
            if job is not None:
                self._message(job, msg[0], msg[2:])
        for job in list(by_key.values()):
            final = job.futures[-1]
            failed = next((f for f in job.futures if f.status in ("error", "cancelled")),
                          None)
            if final.status == "finished":
                self._end(job, "succeeded", result_json=final.result())
            elif failed is not None:
                self._failed(job, failed)

    def _message(self, job: _Job, tag: str, body: tuple) -> None:
        if tag == "start":
            index = body[0]
            job.starts[index] += 1
            if job.starts[index] > 1:  # the scheduler re-ran it: its worker was lost
                self.store.count_attempt(job.id, f"step {index + 1} re-run on another worker")
        elif tag == "progress" and job.tracker is not None:
            job.tracker.report(*body)

    def _failed(self, job: _Job, fut: Any) -> None:
        if fut.status == "cancelled":
            # Not ours (we drop a job's futures before cancelling them): the client lost the
            # scheduler under it; the job waits for the connection to come back.
            if self.client is not None and self.client.status == "running":
                log.warning("job %s: its tasks were dropped by the cluster; handing it over "
                            "again", job.id)
                self._hand_over(job)
            return
        exc = fut.exception()
        if isinstance(exc, StepCancelled | SchedulerLost):
            # Not a cancel or a time limit of ours (those end the job before its tasks
            # report): the step stopped because its worker lost a scheduler (a worker of the
            # old one, briefly registered with the new). The job is handed over again.
            log.warning("job %s: a step stopped on a worker that lost its scheduler; handing "
                        "the job over again", job.id)
            self._hand_over(job)
        else:
            text = str(exc) if isinstance(exc, StepFailed) else f"{type(exc).__name__}: {exc}"
            self._end(job, "failed", error=text)

    def _hand_over(self, job: _Job) -> None:
        """Stop what is left of the job's attempt on the cluster and submit it again."""
        self._signal_cancel(job)
        self._release(job)
        self._submit(job, again=True)

    def _end(self, job: _Job, status: str, *, result_json: str | None = None,
             error: str | None = None) -> None:
        asked = self._take_cancel(job.id)
        self._jobs.pop(job.id, None)
        if asked:
            status, result_json, error = "cancelled", None, None
        message = {"succeeded": "done", "cancelled": "cancelled"}.get(status, "failed")
        self.store.finish_job(job.id, status, result_json=result_json, error=error,
                              message=message)
        self._release(job)

    def _release(self, job: _Job) -> None:
        """Stop the job's tasks and drop their futures."""
        futures = [f for f in [*job.futures, job.payload_future] if f is not None]
        job.futures, job.payload_future = [], None
        if self.client is None:
            return
        try:
            self.client.cancel(futures)
        except Exception:  # noqa: BLE001 - best effort; the scheduler may be gone
            pass

    def _signal_cancel(self, job: _Job) -> None:
        if self.client is None:
            return
        from distributed import Event

        try:
            Event(_cancel_name(job.key), client=self.client).set()
        except Exception:  # noqa: BLE001 - lost: its tasks end with their worker's session
            pass

    def _write_progress(self) -> None:
        for job in self._jobs.values():
            if job.tracker is not None:
                self._save_progress(job.id, job.tracker)

    def _handle_time_limits(self) -> None:
        """Fail the jobs past their time limit now; stop their tasks as a cancel does."""
        overdue = self._overdue({j.id: j.deadline for j in self._jobs.values()})
        for job_id in overdue:
            job = self._jobs.pop(job_id)
            self._signal_cancel(job)
            self._release(job)
            self._take_cancel(job_id)
            self._fail_over_time(job_id, job.time_limit_s or 0.0)

    def _handle_cancels(self) -> None:
        for job_id in self._cancel_requested(set(self._jobs)):
            job = self._jobs[job_id]
            self._signal_cancel(job)
            self._end(job, "cancelled")


def _close_quietly(client: Any) -> None:
    try:
        client.close(timeout=2)
    except Exception:  # noqa: BLE001 - a client of a dead scheduler may fail to close
        pass

