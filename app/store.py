"""The service's SQLite store (``<data_dir>/kinoplan.sqlite3``): custom robots and jobs.

One file holds every table; ``PRAGMA user_version`` records which of ``_MIGRATIONS`` have
run, so a later table (jobs) is one more entry there. The store is called from FastAPI's
thread pool: every call opens its own connection (cheap for a local file) and runs in one
transaction, so a crash never leaves half a write, and WAL mode lets readers proceed while
one writer commits.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

__all__ = ["Store", "StoredRobot", "JobRecord", "DuplicateError", "STORE_FILENAME", "now_iso"]

STORE_FILENAME = "kinoplan.sqlite3"

# Applied in order, each once; entry k brings the schema to user_version k + 1.
_MIGRATIONS: tuple[str, ...] = (
    """
    CREATE TABLE IF NOT EXISTS robots (
        id TEXT PRIMARY KEY,
        model_json TEXT NOT NULL,
        created TEXT NOT NULL
    );
    """,
    """
    CREATE TABLE IF NOT EXISTS jobs (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        id TEXT UNIQUE NOT NULL,
        kind TEXT NOT NULL,
        params_json TEXT NOT NULL,
        payload_json TEXT NOT NULL,
        status TEXT NOT NULL,
        progress REAL NOT NULL DEFAULT 0,
        message TEXT NOT NULL DEFAULT '',
        created TEXT NOT NULL,
        started TEXT,
        finished TEXT,
        error TEXT,
        attempts INTEGER NOT NULL DEFAULT 0,
        cancel_requested INTEGER NOT NULL DEFAULT 0,
        result_json TEXT
    );
    CREATE INDEX IF NOT EXISTS jobs_status ON jobs (status, seq);
    """,
)


def now_iso() -> str:
    """The current UTC time, ISO 8601 with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


class DuplicateError(Exception):
    """A row with this id already exists."""


@dataclass(frozen=True)
class JobRecord:
    """One job. ``params`` as submitted; ``payload`` what the worker gets (params plus what
    the service resolved, e.g. the robot model). Times are UTC ISO strings or None."""

    id: str
    kind: str
    params: dict
    status: str
    progress: float
    message: str
    created: str
    started: str | None
    finished: str | None
    error: str | None
    attempts: int
    cancel_requested: bool

    def to_dict(self) -> dict:
        return {
            "id": self.id, "kind": self.kind, "params": self.params, "status": self.status,
            "progress": self.progress, "message": self.message, "created": self.created,
            "started": self.started, "finished": self.finished, "error": self.error,
            "attempts": self.attempts,
        }


_JOB_COLUMNS = (
    "id, kind, params_json, status, progress, message, created, started, finished, error, "
    "attempts, cancel_requested"
)


def _job(row: tuple) -> JobRecord:
    return JobRecord(row[0], row[1], json.loads(row[2]), *row[3:11], bool(row[11]))


@dataclass(frozen=True)
class StoredRobot:
    """One row of ``robots``: the model JSON text as stored and its UTC ISO creation time."""

    id: str
    model_json: str
    created: str


class Store:
    """The SQLite file at ``path`` (created with its directory if missing)."""

    def __init__(self, path: Path | str, *, timeout_s: float = 30.0) -> None:
        self.path = Path(path)
        self.timeout_s = timeout_s
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._migrate()

    @classmethod
    def in_data_dir(cls, data_dir: Path | str) -> Store:
        """The service's store: ``<data_dir>/kinoplan.sqlite3``."""
        return cls(Path(data_dir) / STORE_FILENAME)

    @contextmanager
    def _connect(self) -> Iterator[sqlite3.Connection]:
        """A fresh connection whose block is one transaction (commit, or roll back on error)."""
        conn = sqlite3.connect(self.path, timeout=self.timeout_s)
        try:
            with conn:
                yield conn
        finally:
            conn.close()

    def _migrate(self) -> None:
        with self._connect() as conn:
            # WAL is a property of the file: set once, every later connection uses it.
            conn.execute("PRAGMA journal_mode=WAL")
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")  # one process migrates at a time
            version = conn.execute("PRAGMA user_version").fetchone()[0]
            for k in range(version, len(_MIGRATIONS)):
                for statement in _MIGRATIONS[k].split(";"):
                    if statement.strip():
                        conn.execute(statement)
            if version < len(_MIGRATIONS):
                conn.execute(f"PRAGMA user_version = {len(_MIGRATIONS)}")

    # ---- robots -------------------------------------------------------------------------
    def put_robot(self, robot_id: str, model_json: str) -> StoredRobot:
        """Insert a robot; ``DuplicateError`` if ``robot_id`` is already stored."""
        created = now_iso()
        try:
            with self._connect() as conn:
                conn.execute(
                    "INSERT INTO robots (id, model_json, created) VALUES (?, ?, ?)",
                    (robot_id, model_json, created),
                )
        except sqlite3.IntegrityError:
            raise DuplicateError(robot_id) from None
        return StoredRobot(robot_id, model_json, created)

    def get_robot(self, robot_id: str) -> StoredRobot:
        """The stored robot ``robot_id``; ``KeyError`` if there is none."""
        with self._connect() as conn:
            row = conn.execute(
                "SELECT id, model_json, created FROM robots WHERE id = ?", (robot_id,)
            ).fetchone()
        if row is None:
            raise KeyError(robot_id)
        return StoredRobot(*row)

    def list_robots(self) -> list[StoredRobot]:
        """Every stored robot, oldest first."""
        with self._connect() as conn:
            rows = conn.execute(
                "SELECT id, model_json, created FROM robots ORDER BY rowid"
            ).fetchall()
        return [StoredRobot(*row) for row in rows]

    def delete_robot(self, robot_id: str) -> bool:
        """Delete ``robot_id``; whether there was such a row."""
        with self._connect() as conn:
            cur = conn.execute("DELETE FROM robots WHERE id = ?", (robot_id,))
        return cur.rowcount > 0

    # ---- jobs ---------------------------------------------------------------------------
    def add_job(self, job_id: str, kind: str, params: dict, payload: dict,
                max_queued: int | None = None) -> JobRecord | None:
        """Queue a job; None (nothing written) when ``max_queued`` jobs are already queued."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            if max_queued is not None:
                (queued,) = conn.execute(
                    "SELECT COUNT(*) FROM jobs WHERE status = 'queued'").fetchone()
                if queued >= max_queued:
                    return None
            conn.execute(
                "INSERT INTO jobs (id, kind, params_json, payload_json, status, created) "
                "VALUES (?, ?, ?, ?, 'queued', ?)",
                (job_id, kind, json.dumps(params), json.dumps(payload), now_iso()),
            )
        return self.get_job(job_id)

    def get_job(self, job_id: str) -> JobRecord:
        """The job ``job_id``; KeyError if there is none."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {_JOB_COLUMNS} FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
        if row is None:
            raise KeyError(job_id)
        return _job(row)

    def list_jobs(self, status: str | None = None, limit: int | None = None) -> list[JobRecord]:
        """Jobs in submission order (optionally of one status, at most ``limit``)."""
        sql = f"SELECT {_JOB_COLUMNS} FROM jobs"
        args: tuple = ()
        if status is not None:
            sql += " WHERE status = ?"
            args = (status,)
        sql += " ORDER BY seq"
        if limit is not None:
            sql += f" LIMIT {int(limit)}"
        with self._connect() as conn:
            return [_job(r) for r in conn.execute(sql, args).fetchall()]

    def job_payload(self, job_id: str) -> dict:
        with self._connect() as conn:
            row = conn.execute("SELECT payload_json FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
        if row is None:
            raise KeyError(job_id)
        return json.loads(row[0])

    def job_result(self, job_id: str) -> str | None:
        """The result JSON text of a job (None until it has one)."""
        with self._connect() as conn:
            row = conn.execute("SELECT result_json FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
        if row is None:
            raise KeyError(job_id)
        return row[0]

    def claim_next_job(self) -> JobRecord | None:
        """Mark the oldest queued job running and return it (None if none is queued)."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            row = conn.execute(
                "SELECT id FROM jobs WHERE status = 'queued' ORDER BY seq LIMIT 1").fetchone()
            if row is None:
                return None
            conn.execute(
                "UPDATE jobs SET status = 'running', started = ?, attempts = attempts + 1, "
                "message = 'started', progress = 0 WHERE id = ?", (now_iso(), row[0]))
        return self.get_job(row[0])

    def set_progress(self, job_id: str, progress: float, message: str) -> None:
        with self._connect() as conn:
            conn.execute(
                "UPDATE jobs SET progress = ?, message = ? WHERE id = ? AND status = 'running'",
                (progress, message, job_id))

    def finish_job(self, job_id: str, status: str, *, result_json: str | None = None,
                   error: str | None = None, message: str = "") -> bool:
        """End a queued or running job with ``status``; False if it had already ended."""
        progress_sql = ", progress = 1" if status == "succeeded" else ""
        with self._connect() as conn:
            cur = conn.execute(
                f"UPDATE jobs SET status = ?, finished = ?, result_json = ?, error = ?, "
                f"message = ?{progress_sql} WHERE id = ? AND status IN ('queued', 'running')",
                (status, now_iso(), result_json, error, message, job_id))
        return cur.rowcount > 0

    def request_cancel(self, job_id: str) -> JobRecord:
        """Cancel a queued job at once; flag a running one for the backend to stop."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            conn.execute(
                "UPDATE jobs SET status = 'cancelled', finished = ?, message = 'cancelled' "
                "WHERE id = ? AND status = 'queued'", (now_iso(), job_id))
            conn.execute(
                "UPDATE jobs SET cancel_requested = 1 WHERE id = ? AND status = 'running'",
                (job_id,))
        return self.get_job(job_id)

    def requeue_interrupted(self, max_attempts: int) -> tuple[int, int]:
        """After a restart: jobs left running are queued again, or failed once they have
        been interrupted ``max_attempts`` times. Returns (re-queued, failed)."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            failed = conn.execute(
                "UPDATE jobs SET status = 'failed', finished = ?, error = ?, message = ? "
                "WHERE status = 'running' AND attempts >= ?",
                (now_iso(), f"interrupted by {max_attempts} service restarts",
                 "interrupted", max_attempts)).rowcount
            requeued = conn.execute(
                "UPDATE jobs SET status = 'queued', progress = 0, started = NULL, "
                "message = 're-queued after a service restart' WHERE status = 'running'"
            ).rowcount
            # A cancel asked for before the restart is honoured now.
            conn.execute(
                "UPDATE jobs SET status = 'cancelled', finished = ?, message = 'cancelled' "
                "WHERE status = 'queued' AND cancel_requested = 1", (now_iso(),))
        return requeued, failed

    def count_jobs(self, status: str) -> int:
        with self._connect() as conn:
            return conn.execute("SELECT COUNT(*) FROM jobs WHERE status = ?",
                                (status,)).fetchone()[0]
