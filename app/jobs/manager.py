"""The job manager: validates submissions, keeps records in the store, drives a backend."""

from __future__ import annotations

import logging
import threading
import uuid
from datetime import UTC, datetime, timedelta
from typing import Any

from pydantic import ValidationError

from kinematics.errors import FieldError

from ..registry import CollisionNotReady, RobotRegistry
from ..store import JobRecord, Store
from .caps import DEFAULT_TIME_LIMIT_S, ParamsLimitError, check_params
from .catalog import KINDS, get_kind
from .kinds import JobPayload, Submission

__all__ = ["JobManager", "JobParamsError", "QueueFullError", "JobStateError",
           "BackendUnavailable", "MAX_ATTEMPTS", "make_backend"]

log = logging.getLogger(__name__)

#: A job started this many times without finishing (service restarts, lost workers) is
#: failed at the next start of the service instead of run again.
MAX_ATTEMPTS = 3

#: Seconds between two passes that prune finished jobs (retention) and compact the store.
MAINTENANCE_EVERY_S = 60.0


def served_kinds() -> tuple[str, ...]:
    """Kinds the service serves from after they end (``JobKind.keep_latest``; the learned IK
    of ``model_kinds.IK_TRAIN``): the latest succeeded job of each per robot is never pruned,
    only deleted on request."""
    return tuple(name for name, kind in KINDS.items() if kind.keep_latest)


#: ``served_kinds()`` of the catalog's kinds.
SERVED_KINDS = served_kinds()


class JobParamsError(ValueError):
    """Invalid job submission; ``loc`` names the field (e.g. ``["params", "samples"]``)."""

    def __init__(self, loc: list, message: str, status: int = 422):
        super().__init__(message)
        self.loc = loc
        self.message = message
        self.status = status


def _params_error(err: dict[str, Any]) -> tuple[list, str]:
    """``loc`` and message of a params validation error. A ``FieldError`` raised by a
    field's validator (a domain check of kinematics or planning) names its field relative to
    the params; that ``loc`` is kept when it is the field validated or a part of it
    (``params.population`` of ``params``), otherwise pydantic's location stands."""
    where = tuple(err["loc"])
    cause = (err.get("ctx") or {}).get("error")
    if isinstance(cause, FieldError) and where and cause.loc[:len(where)] == where:
        return ["params", *cause.loc], cause.message
    return ["params", *where], err["msg"]


class QueueFullError(RuntimeError):
    """As many jobs are queued as the service accepts."""


class JobStateError(RuntimeError):
    """The job is not in a state that allows the request (e.g. its result is not ready)."""


class BackendUnavailable(RuntimeError):
    """The job backend cannot take jobs now (its cluster is unreachable): 503."""


def make_backend(store: Store, jobs_backend: str, workers: int, *,
                 cluster_deadline_s: float | None = None):
    """The backend named by ``--jobs-backend``: 'local', or a Dask scheduler's address
    'dask://HOST:PORT' (= 'tcp://HOST:PORT') or 'tls://HOST:PORT'."""
    if jobs_backend == "local":
        from .local import LocalBackend

        return LocalBackend(store, workers)
    for prefix, protocol in (("dask://", "tcp://"), ("tcp://", "tcp://"), ("tls://", "tls://")):
        if jobs_backend.startswith(prefix):
            from .dask_backend import DEFAULT_DEADLINE_S, DaskBackend

            return DaskBackend(store, protocol + jobs_backend.removeprefix(prefix), workers,
                               cluster_deadline_s or DEFAULT_DEADLINE_S)
    raise ValueError("jobs_backend must be 'local', 'dask://HOST:PORT' or 'tls://HOST:PORT', "
                     f"got {jobs_backend!r}")


class JobManager:
    """Jobs of one service. The backend is created and started by ``start`` (the service's
    lifespan), so building an app for a test starts no processes."""

    def __init__(self, store: Store, registry: RobotRegistry, jobs_backend: str, workers: int,
                 max_queued: int, time_limit_s: float = DEFAULT_TIME_LIMIT_S,
                 cluster_deadline_s: float | None = None, retention_days: float = 0.0,
                 retention_count: int = 0) -> None:
        self.store = store
        #: Finished jobs are pruned this many days after they ended, and beyond the newest
        #: ``retention_count`` (``Settings.job_retention_*``); 0: no such limit.
        self.retention_days = retention_days
        self.retention_count = retention_count
        self._maintenance: threading.Thread | None = None
        self._stop_maintenance = threading.Event()
        #: Seconds the Dask backend waits for a lost scheduler (``Settings.cluster_deadline_s``).
        self.cluster_deadline_s = cluster_deadline_s
        #: Seconds a job may run unless it asks for less (``Settings.job_time_limit_s``).
        self.time_limit_s = time_limit_s
        self.registry = registry
        self.jobs_backend = jobs_backend
        self.workers = workers
        self.max_queued = max_queued
        self.backend = None
        self._learned: dict[str, tuple[str, object]] = {}
        #: The stored scenes (``app.scenes.SceneRegistry``) path jobs may name; None: none.
        self.scenes: Any = None

    # ---- lifecycle ------------------------------------------------------------------------
    def start(self) -> None:
        requeued, failed = self.store.requeue_interrupted(MAX_ATTEMPTS)
        if requeued or failed:
            log.warning("after restart: %d interrupted job(s) queued again, %d failed",
                        requeued, failed)
        # Before any job runs or request is served (the lifespan runs before the port
        # opens): the first compaction of a store made before payloads were dropped rewrites
        # it (VACUUM), which would stall every write meanwhile.
        self._maintain_logged(set())
        self.backend = make_backend(self.store, self.jobs_backend, self.workers,
                                    cluster_deadline_s=self.cluster_deadline_s)
        self.backend.start()
        self._stop_maintenance.clear()
        self._maintenance = threading.Thread(target=self._maintenance_loop, daemon=True,
                                             name="kinoplan-job-retention")
        self._maintenance.start()

    def stop(self) -> None:
        self._stop_maintenance.set()
        if self._maintenance is not None:
            self._maintenance.join(timeout=10)
            self._maintenance = None
        if self.backend is not None:
            self.backend.stop()
            self.backend = None

    def maintain(self) -> tuple[int, int]:
        """Prune the finished jobs the retention settings no longer keep, then give the
        store's free pages back to the file system when they are worth it
        (``Store.compact``): (jobs deleted, bytes the store shrank by)."""
        before = None
        if self.retention_days > 0:
            before = (datetime.now(UTC) - timedelta(days=self.retention_days)).isoformat(
                timespec="microseconds")
        pruned = self.store.prune_jobs(finished_before=before,
                                       keep=self.retention_count or None,
                                       keep_latest=served_kinds())
        if pruned:
            log.info("pruned %d finished job(s) past their retention", pruned)
        freed = self.store.compact()
        if freed:
            log.info("compacted the store at %s: %.1f MB given back", self.store.path,
                     freed / 1e6)
        return pruned, freed

    def _maintain_logged(self, logged: set[str]) -> None:
        """``maintain``, its failures logged once each (the store may be down a while)."""
        try:
            self.maintain()
        except Exception as exc:  # noqa: BLE001 - the store may be down: retried later
            message = f"{type(exc).__name__}: {exc}"
            if message not in logged:
                logged.add(message)
                log.warning("job retention pass failed (retried every %g s): %s",
                            MAINTENANCE_EVERY_S, message)
        else:
            logged.clear()

    def _maintenance_loop(self) -> None:
        logged: set[str] = set()
        while not self._stop_maintenance.wait(MAINTENANCE_EVERY_S):
            self._maintain_logged(logged)

    @property
    def running(self) -> bool:
        return self.backend is not None and self.backend.alive()

    # ---- requests -------------------------------------------------------------------------
    def unavailable(self) -> str | None:
        """Why the backend takes no jobs now (its cluster is unreachable); None: it does."""
        return None if self.backend is None else self.backend.unavailable()

    def submit(self, kind: str, params: dict[str, Any], time_limit_s: float | None = None,
               max_time_limit_s: float | None = None) -> JobRecord:
        """Validate and queue a job; raises JobParamsError, QueueFullError or
        BackendUnavailable (after the params were found valid). The job may run
        ``time_limit_s`` seconds (default and most: ``max_time_limit_s``, itself by default
        the manager's ``time_limit_s``)."""
        if max_time_limit_s is None:
            max_time_limit_s = self.time_limit_s
        if kind not in KINDS:
            raise JobParamsError(["kind"], f"unknown job kind {kind!r}; known: "
                                 f"{', '.join(sorted(KINDS))}")
        spec = get_kind(kind)
        if not isinstance(params, dict):
            raise JobParamsError(["params"], "params must be a JSON object")
        if time_limit_s is None:
            time_limit_s = max_time_limit_s
        elif time_limit_s > max_time_limit_s:
            raise JobParamsError(["time_limit_s"], f"at most {max_time_limit_s:g} s on this "
                                 f"service, got {time_limit_s:g}")
        submission = Submission(self.scenes, self.registry)
        try:  # size first: an oversized submission costs no validation
            check_params(params, spec.max_params_bytes)
            params = spec.prepared(params, submission)
        except ParamsLimitError as exc:
            raise JobParamsError(exc.loc, exc.message, exc.status) from None
        try:
            checked = spec.load_params(params)
        except ValidationError as exc:
            raise JobParamsError(*_params_error(exc.errors()[0])) from None
        if spec.check is not None:
            try:
                spec.check(checked, submission)
            except ParamsLimitError as exc:
                raise JobParamsError(exc.loc, exc.message, exc.status) from None
        clean = checked.model_dump(mode="json")
        payload = JobPayload(params=clean)
        robot = spec.robot_id(checked)
        if spec.needs_robot or robot is not None:
            try:
                payload.robot_model = self.registry.get(robot).to_dict()
                if spec.needs_geometry:
                    payload.robot_files = self.registry.robot_files(robot)
            except KeyError:
                raise JobParamsError(["params", "robot"], f"unknown robot '{robot}'",
                                     status=404) from None
            except CollisionNotReady as exc:
                raise JobParamsError(["params", "robot"], str(exc), status=409) from None
        why = self.unavailable()
        if why is not None:
            raise BackendUnavailable(why)
        job = self.store.add_job(uuid.uuid4().hex[:16], kind, clean,
                                 payload.model_dump(mode="json", exclude=(
                                     {"robot_files"} if payload.robot_files is None
                                     else None)),
                                 max_queued=self.max_queued, time_limit_s=time_limit_s)
        if job is None:
            raise QueueFullError(f"{self.max_queued} jobs are already queued; try again later")
        if self.backend is not None:
            self.backend.notify()
        return job

    def get(self, job_id: str) -> JobRecord:
        return self.store.get_job(job_id)

    def list(self, status: str | None = None, kind: str | None = None,
             limit: int | None = None, offset: int = 0) -> list[JobRecord]:
        """Jobs oldest first, optionally of one status and kind, a page at a time."""
        return self.store.list_jobs(status, limit, kind=kind, offset=offset)

    def count(self, status: str | None = None, kind: str | None = None) -> int:
        return self.store.count_jobs(status, kind)

    def result(self, job_id: str) -> str:
        """The result JSON text; KeyError if unknown, JobStateError unless succeeded."""
        job = self.store.get_job(job_id)
        if job.status != "succeeded":
            why = f": {job.error}" if job.error else ""
            raise JobStateError(f"job {job_id} is {job.status}, no result{why}")
        text = self.store.job_result(job_id)
        assert text is not None
        return text

    def delete(self, job_id: str) -> JobRecord | None:
        """``DELETE /jobs/{id}``: cancel a queued or running job (its record, as ``cancel``),
        or delete one that has ended, with its result (None). KeyError if unknown."""
        for _ in range(2):  # a job that ends between the two looks is deleted
            if self.store.delete_ended_job(job_id) is not None:
                return None
            try:
                return self.cancel(job_id)
            except JobStateError:
                continue
        raise JobStateError(f"job {job_id} could not be cancelled or deleted; try again")

    def cancel(self, job_id: str) -> JobRecord:
        """Cancel a queued job at once or stop a running one; JobStateError if it ended."""
        job = self.store.get_job(job_id)
        if job.status not in ("queued", "running"):
            raise JobStateError(f"job {job_id} has already ended ({job.status})")
        job = self.store.request_cancel(job_id)
        if job.status == "running" and self.backend is not None:
            self.backend.cancel(job_id)
        return job

    def learned_ik(self, robot_id: str):
        """The learned IK of the latest succeeded ``IK_TRAIN`` job for ``robot_id`` (cached),
        with that job's id; None if there is none; ``model_kinds.LearnedIKRefused`` if that
        model failed its validation (an older model that passed does not stand in: the latest
        training is the one asked for). One indexed query per call; the result of a job is
        read (and parsed as ``IKTrainResult``) only when it is newer than the cache."""
        from .model_kinds import IK_TRAIN, LearnedIKRefused, served_learned_ik

        latest = self.store.latest_job_for_robot(IK_TRAIN.name, robot_id)
        if latest is None:
            self._learned.pop(robot_id, None)  # its job was deleted: its model goes too
            return None
        cached = self._learned.get(robot_id)
        if cached is None or cached[0] != latest.id:
            try:
                text = self.store.job_result(latest.id)
            except KeyError:  # deleted since the look-up: the one before it serves, if any
                return self.learned_ik(robot_id)
            assert text is not None  # a succeeded job has its result
            try:
                cached = (latest.id, served_learned_ik(robot_id, latest.id, text))
            except LearnedIKRefused as exc:
                cached = (latest.id, str(exc))
            self._learned[robot_id] = cached
        if isinstance(cached[1], str):
            raise LearnedIKRefused(cached[1])
        return cached
