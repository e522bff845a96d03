"""The service's SQLite store (``<data_dir>/kinoplan.sqlite3``): custom and imported robots
(with their mesh files), scenes, uploaded meshes and jobs.

One file holds every table; ``PRAGMA user_version`` records which of ``_MIGRATIONS`` have
run, so a later table (jobs) is one more entry there. The store is called from FastAPI's
thread pool: every call opens its own connection (cheap for a local file) and runs in one
transaction, so a crash never leaves half a write, and WAL mode lets readers proceed while
one writer commits.

A job's payload (what its worker needs: an imported robot's meshes can take megabytes) is
kept only while the job is queued or running; finished jobs keep their record and result
until deleted (``DELETE /jobs/{id}``, or pruned by the retention settings). The pages freed
stay in the file for later rows until ``compact`` gives them back.

When the file becomes unusable (deleted, replaced by something that is not a database,
corrupt, read-only, disk full) every call raises ``StoreError`` (the API answers 503) and
the change is logged once. The store never creates the file again behind the operator's
back: a vanished file stays an error until a file is back at the path. Whatever file is
there then (a restored backup, a repaired copy, even an empty file) is picked up by the
next call, with any missing migrations applied, without a restart.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

__all__ = ["Store", "StoredRobot", "JobRecord", "DuplicateError", "StoreError",
           "StoreMirror", "StoreUsage", "STORE_FILENAME", "ENDED", "now_iso"]

log = logging.getLogger(__name__)

STORE_FILENAME = "kinoplan.sqlite3"
#: Seconds a health check result is reused (``Store.health``).
HEALTH_TTL_S = 1.0
#: Busy timeout (s) of the health check's connection: a check never waits long on a lock.
HEALTH_TIMEOUT_S = 0.5
#: A failed write (disk full, read-only, I/O error) counts against the store's health for
#: this many seconds after it was last seen, unless a later write succeeds first.
WRITE_FAILURE_HOLD_S = 30.0
#: Less free space than this on the store's file system makes the store unhealthy.
MIN_FREE_BYTES = 1 << 20
# SQLite primary result codes of a failed write: the file may still be readable.
_WRITE_FAILURES = {sqlite3.SQLITE_FULL, sqlite3.SQLITE_READONLY, sqlite3.SQLITE_IOERR}

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
    """
    ALTER TABLE jobs ADD COLUMN time_limit_s REAL;
    CREATE INDEX IF NOT EXISTS jobs_kind ON jobs (kind, seq);
    """,
    """
    ALTER TABLE robots ADD COLUMN description_json TEXT;
    CREATE TABLE IF NOT EXISTS robot_meshes (
        robot_id TEXT NOT NULL,
        key TEXT NOT NULL,
        data BLOB NOT NULL,
        PRIMARY KEY (robot_id, key)
    );
    CREATE TABLE IF NOT EXISTS scenes (
        id TEXT PRIMARY KEY,
        scene_json TEXT NOT NULL,
        created TEXT NOT NULL
    );
    CREATE TABLE IF NOT EXISTS meshes (
        id TEXT PRIMARY KEY,
        info_json TEXT NOT NULL,
        data BLOB NOT NULL,
        created TEXT NOT NULL
    );
    """,
    # Payloads (megabytes for an imported robot's meshes) live apart from the job records,
    # only while the job is queued or running: a progress write then rewrites a small row,
    # and a job that ends drops its payload. ``jobs.payload_json`` stays, always ''.
    """
    CREATE TABLE IF NOT EXISTS job_payloads (
        job_id TEXT PRIMARY KEY,
        payload_json TEXT NOT NULL
    );
    INSERT OR IGNORE INTO job_payloads (job_id, payload_json)
        SELECT id, payload_json FROM jobs WHERE status IN ('queued', 'running');
    UPDATE jobs SET payload_json = '' WHERE payload_json <> '';
    """,
)


def now_iso() -> str:
    """The current UTC time, ISO 8601 with microseconds."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


class DuplicateError(Exception):
    """A row with this id already exists."""


class StoreError(Exception):
    """The store cannot be used: its file is missing, not a database, corrupt, read-only, or
    the disk is full. ``reason`` says why without the file's path; ``str()`` names both."""

    def __init__(self, path: Path, reason: str, code: int | None = None) -> None:
        super().__init__(f"cannot use the store at {path}: {reason}")
        self.path = path
        self.reason = reason
        #: SQLite's primary result code, when SQLite reported the error.
        self.code = code


@dataclass(frozen=True)
class JobRecord:
    """One job. ``params`` as submitted; its payload (``Store.job_payload``: params plus what
    the service resolved, e.g. the robot model) is kept apart, until the job ends. Times are
    UTC ISO strings or None."""

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
    #: Seconds the job may run (None: no limit, for jobs queued before limits existed).
    time_limit_s: float | None = None

    def to_dict(self) -> dict:
        return {
            "id": self.id, "kind": self.kind, "params": self.params, "status": self.status,
            "progress": self.progress, "message": self.message, "created": self.created,
            "started": self.started, "finished": self.finished, "error": self.error,
            "attempts": self.attempts, "time_limit_s": self.time_limit_s,
        }


_JOB_COLUMNS = (
    "id, kind, params_json, status, progress, message, created, started, finished, error, "
    "attempts, cancel_requested, time_limit_s"
)


#: The statuses of a job that has ended: it never runs again.
ENDED = ("succeeded", "failed", "cancelled")
_ENDED_SQL = "(" + ", ".join(f"'{status}'" for status in ENDED) + ")"
# Payloads of jobs that cannot run again (ended, or deleted) are dropped.
_DROP_ENDED_PAYLOADS = ("DELETE FROM job_payloads WHERE job_id NOT IN "
                        "(SELECT id FROM jobs WHERE status IN ('queued', 'running'))")
#: Free pages worth less than this stay in the file for the next payloads (``compact``).
COMPACT_MIN_FREE_BYTES = 16 << 20


def _job(row: tuple) -> JobRecord:
    return JobRecord(row[0], row[1], json.loads(row[2]), *row[3:11], bool(row[11]), row[12])


def _job_filter(status: str | None, kind: str | None) -> tuple[str, tuple]:
    """The WHERE clause (with its arguments) selecting jobs of a status and a kind."""
    terms = [(name, value) for name, value in (("status", status), ("kind", kind))
             if value is not None]
    if not terms:
        return "", ()
    return " WHERE " + " AND ".join(f"{name} = ?" for name, _ in terms), \
        tuple(value for _, value in terms)


@dataclass(frozen=True)
class StoreUsage:
    """What the store takes on disk, read with its health check."""

    #: Bytes of its files (the database, its write-ahead log and shared-memory index).
    bytes: int
    #: Bytes of free pages inside the database file (given back by ``Store.compact``).
    free_bytes: int
    #: Jobs by status, every status named.
    jobs: dict[str, int]


@dataclass(frozen=True)
class StoredRobot:
    """One row of ``robots``: the model JSON text as stored and its UTC ISO creation time."""

    id: str
    model_json: str
    created: str
    #: An imported robot's description (links, geometry, collision rules) as JSON text;
    #: None for robots given as a model JSON.
    description_json: str | None = None


@dataclass(frozen=True)
class StoredScene:
    """One row of ``scenes``: the scene JSON text and its UTC ISO creation time."""

    id: str
    scene_json: str
    created: str


@dataclass(frozen=True)
class StoredMesh:
    """One row of ``meshes`` without its data: ``info_json`` (name, counts, bounds)."""

    id: str
    info_json: str
    created: str


class StoreMirror:
    """Base of the registries that keep rows of a store in memory: ``_refresh()`` calls
    ``_reload()`` (the subclass's: read the rows again) once the store has moved on to another
    file or works again after it could not be read (its ``generation`` changed); while the
    store is still unusable what was loaded is kept and the next call tries again."""

    def __init__(self, store: Store | None) -> None:
        self._store = store
        self._lock = threading.Lock()
        self._generation = store.generation if store is not None else 0

    def _reload(self) -> None:  # pragma: no cover - every subclass has its own
        raise NotImplementedError

    def _refresh(self) -> bool:
        """Whether the rows were read again now."""
        store = self._store
        if store is None or store.generation == self._generation:
            return False
        with self._lock:
            generation = store.generation
            if generation == self._generation:
                return False
            try:
                self._reload()
            except StoreError:  # still unusable: serve what we have, retry later
                return False
            self._generation = generation
            return True


class Store:
    """The SQLite file at ``path`` (created with its directory if missing).

    Construction raises ``StoreError`` when the file cannot be used (a directory or a
    read-only file in its place, not a database, an unwritable data directory).
    """

    def __init__(self, path: Path | str, *, timeout_s: float = 30.0) -> None:
        self.path = Path(path)
        self.timeout_s = timeout_s
        #: Bumped when the store starts using another file at its path (a restored backup) or
        #: the file works again after it could not be read, so caches of rows reload.
        self.generation = 0
        self._uri = self.path.absolute().as_uri()
        self._state_lock = threading.Lock()
        self._identity: tuple[int, int] | None = None  # (device, inode) of the file in use
        self._failure: str | None = None  # why the last call failed, until one succeeds
        self._write_failure: tuple[float, str] | None = None  # (when, why) of a failed write
        self._health_lock = threading.Lock()
        self._health: tuple[float, str | None] | None = None  # (when, why unhealthy)
        self._usage: StoreUsage | None = None  # read by the last health check that could
        parent = self.path.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            why = (f"{parent} is not a directory" if parent.exists() and not parent.is_dir()
                   else f"cannot create the directory {parent}: {exc.strerror or exc}")
            raise StoreError(self.path, why) from exc
        try:
            self._migrate(create=True)
            self._identity = self._stat()
            conn = self._open()
            try:  # take the write lock once: a file SQLite may not write fails here
                conn.execute("BEGIN IMMEDIATE")
                conn.rollback()
            finally:
                conn.close()
        except (sqlite3.Error, OSError) as exc:
            raise self._error(exc) from exc
        why = self._unwritable()
        if why is not None:
            raise StoreError(self.path, why)

    @classmethod
    def in_data_dir(cls, data_dir: Path | str) -> Store:
        """The service's store: ``<data_dir>/kinoplan.sqlite3``."""
        return cls(Path(data_dir) / STORE_FILENAME)

    def _open(self, *, create: bool = False, timeout_s: float | None = None
              ) -> sqlite3.Connection:
        """A new connection to the file, which must exist unless ``create``."""
        return sqlite3.connect(f"{self._uri}?mode={'rwc' if create else 'rw'}", uri=True,
                               timeout=self.timeout_s if timeout_s is None else timeout_s)

    @contextmanager
    def _connect(self, timeout_s: float | None = None) -> Iterator[sqlite3.Connection]:
        """A fresh connection whose block is one transaction (commit, or roll back on error).

        Errors that mean the file cannot be used are raised as ``StoreError``; integrity and
        programming errors pass through unchanged."""
        try:
            conn = self._open_current(timeout_s)
        except (StoreError, sqlite3.Error, OSError) as exc:
            error = self._failed(exc)
            if error is exc:
                raise
            raise error from exc
        try:
            with conn:
                yield conn
            wrote = conn.total_changes > 0
        except (sqlite3.IntegrityError, sqlite3.ProgrammingError):
            raise
        except sqlite3.DatabaseError as exc:
            raise self._failed(exc) from exc
        finally:
            conn.close()
        self._succeeded(wrote)

    def _migrate(self, *, create: bool = False) -> None:
        """Bring the file to the latest schema; reads only when it is there already."""
        conn = self._open(create=create)
        try:
            if conn.execute("PRAGMA page_count").fetchone()[0] == 0:
                # A new file: only now (before WAL writes its header) can it be made to give
                # freed pages back (``compact``) without a VACUUM.
                conn.execute("PRAGMA auto_vacuum = INCREMENTAL")
            mode = conn.execute("PRAGMA journal_mode").fetchone()[0]
            version = conn.execute("PRAGMA user_version").fetchone()[0]
            if mode.lower() != "wal":
                # WAL is a property of the file: set once, every later connection uses it.
                conn.execute("PRAGMA journal_mode=WAL")
            if version >= len(_MIGRATIONS):
                return
            with conn:
                conn.execute("BEGIN IMMEDIATE")  # one process migrates at a time
                version = conn.execute("PRAGMA user_version").fetchone()[0]
                for k in range(version, len(_MIGRATIONS)):
                    for statement in _MIGRATIONS[k].split(";"):
                        if statement.strip():
                            conn.execute(statement)
                if version < len(_MIGRATIONS):
                    conn.execute(f"PRAGMA user_version = {len(_MIGRATIONS)}")
        finally:
            conn.close()

    # ---- health -------------------------------------------------------------------------
    def _stat(self) -> tuple[int, int]:
        """(device, inode) of the file at ``path``; StoreError unless it is a regular file."""
        try:
            st = os.stat(self.path)
        except FileNotFoundError:
            raise StoreError(self.path, "the store file is missing (deleted or moved)") from None
        if not stat.S_ISREG(st.st_mode):
            raise StoreError(self.path, "the store path is not a regular file")
        return st.st_dev, st.st_ino

    def _unwritable(self) -> str | None:
        """Why the file or its directory cannot be written (None when both can)."""
        if not os.access(self.path, os.W_OK):
            return "the store file is read-only"
        if not os.access(self.path.parent, os.W_OK | os.X_OK):
            return "the data directory is read-only"
        return None

    def _error(self, exc: BaseException) -> StoreError:
        """``exc`` (from SQLite or the file system) as a StoreError saying what is wrong."""
        if isinstance(exc, StoreError):
            return exc
        code = getattr(exc, "sqlite_errorcode", None)
        code = None if code is None else code & 0xFF  # primary result code
        if self.path.is_dir():
            reason = "the store path is a directory, not a database file"
        elif code == sqlite3.SQLITE_CANTOPEN and not self.path.exists():
            reason = "the store file is missing (deleted or moved)"
        elif isinstance(exc, OSError):
            reason = exc.strerror or str(exc)
        else:
            reason = str(exc) or type(exc).__name__
        return StoreError(self.path, reason, code)

    def _failed(self, exc: BaseException) -> StoreError:
        """Record a failed call (logged once per distinct reason) and return its error."""
        error = self._error(exc)
        with self._state_lock:
            if error.code in _WRITE_FAILURES:
                self._write_failure = (time.monotonic(), error.reason)
            changed = error.reason != self._failure
            self._failure = error.reason
            if changed:
                self._health = None  # the next health check looks again
        if changed:
            log.warning("%s", error)
        return error

    def _succeeded(self, wrote: bool) -> None:
        """A call worked: the store has recovered unless a write failed and none worked
        since (a read-only file or a full disk still serve reads)."""
        if self._failure is None and self._write_failure is None:
            return
        with self._state_lock:
            failed_write = self._write_failure
            if wrote or (failed_write is not None
                         and time.monotonic() - failed_write[0] > WRITE_FAILURE_HOLD_S):
                self._write_failure = None
            if self._failure is None or self._write_failure is not None:
                return
            self._failure = None
            self._health = None
        log.warning("the store at %s works again", self.path)

    def _open_current(self, timeout_s: float | None) -> sqlite3.Connection:
        """A connection to the file now at ``path``, failing fast when there is none. After
        a failure, when another file has taken the path (a restored backup) or the file
        lacks tables (an emptied one), first apply the migrations it lacks."""
        identity = self._stat()
        conn = self._open(timeout_s=timeout_s)
        try:
            if (identity == self._identity and self._failure is None
                    and conn.execute("PRAGMA user_version").fetchone()[0] >= len(_MIGRATIONS)):
                return conn
        except BaseException:
            conn.close()
            raise
        conn.close()
        with self._state_lock:  # rows may differ unless only writes were failing
            reload_rows = self._failure is None or self._write_failure is None
        self._migrate()
        with self._state_lock:
            replaced = identity != self._identity
            if replaced or reload_rows:
                self.generation += 1
            self._identity = identity
        if replaced:
            log.warning("the store file at %s was replaced; using the new file", self.path)
        return self._open(timeout_s=timeout_s)

    @property
    def health_snapshot(self) -> tuple[float, str | None] | None:
        """The last health check as (``time.monotonic()`` when done, why the store is
        unhealthy or None), without waiting; None when there is none to reuse (say the
        store's state has changed since)."""
        return self._health

    @property
    def usage(self) -> StoreUsage | None:
        """The store's size and jobs by status as the last health check read them; None
        when it could not read them."""
        return self._usage

    def size_bytes(self) -> int:
        """Bytes of the store's files: the database, its write-ahead log and its index."""
        total = 0
        for suffix in ("", "-wal", "-shm"):
            try:
                total += os.stat(f"{self.path}{suffix}").st_size
            except OSError:
                pass
        return total

    def health(self, max_age_s: float = HEALTH_TTL_S) -> str | None:
        """None when the store works, else why not. A real but cheap check: the file is
        there and readable, it and its directory are writable, its file system has room,
        and no write failed lately. A result is reused for ``max_age_s`` seconds."""
        with self._health_lock:
            last = self._health
            if last is not None and time.monotonic() - last[0] < max_age_s:
                return last[1]
            why = self._check_health()
            self._health = (time.monotonic(), why)
            return why

    def _check_health(self) -> str | None:
        self._usage = None
        try:
            with self._connect(timeout_s=HEALTH_TIMEOUT_S) as conn:
                conn.execute("SELECT 1 FROM robots LIMIT 1").fetchall()
                # Counted on the status index alone: cheap for any number of jobs.
                counts = dict.fromkeys(("queued", "running", *ENDED), 0)
                counts.update(conn.execute(
                    "SELECT status, COUNT(*) FROM jobs GROUP BY status").fetchall())
                free = (conn.execute("PRAGMA freelist_count").fetchone()[0]
                        * conn.execute("PRAGMA page_size").fetchone()[0])
            self._usage = StoreUsage(self.size_bytes(), free, counts)
        except StoreError as exc:
            if exc.code != sqlite3.SQLITE_BUSY:  # busy with a long write is not broken
                return exc.reason
        why = self._unwritable()
        if why is not None:
            return why
        if hasattr(os, "statvfs"):
            try:
                fs = os.statvfs(self.path.parent)
            except OSError as exc:
                return exc.strerror or str(exc)
            if fs.f_bavail * fs.f_frsize < MIN_FREE_BYTES:
                return "no space left on the store's file system"
        failed_write = self._write_failure
        if failed_write is not None and time.monotonic() - failed_write[0] < WRITE_FAILURE_HOLD_S:
            return failed_write[1]
        return None

    # ---- robots -------------------------------------------------------------------------
    def put_robot(self, robot_id: str, model_json: str, *, description_json: str | None = None,
                  meshes: dict[str, bytes] | None = None) -> StoredRobot:
        """Insert a robot (with an imported robot's description and mesh files, all in one
        transaction); ``DuplicateError`` if ``robot_id`` is already stored."""
        created = now_iso()
        try:
            with self._connect() as conn:
                conn.execute(
                    "INSERT INTO robots (id, model_json, created, description_json) "
                    "VALUES (?, ?, ?, ?)",
                    (robot_id, model_json, created, description_json),
                )
                conn.execute("DELETE FROM robot_meshes WHERE robot_id = ?", (robot_id,))
                conn.executemany(
                    "INSERT INTO robot_meshes (robot_id, key, data) VALUES (?, ?, ?)",
                    [(robot_id, key, data) for key, data in (meshes or {}).items()],
                )
        except sqlite3.IntegrityError:
            raise DuplicateError(robot_id) from None
        return StoredRobot(robot_id, model_json, created, description_json)

    def get_robot(self, robot_id: str) -> StoredRobot:
        """The stored robot ``robot_id``; ``KeyError`` if there is none."""
        with self._connect() as conn:
            row = conn.execute(
                "SELECT id, model_json, created, description_json FROM robots WHERE id = ?",
                (robot_id,),
            ).fetchone()
        if row is None:
            raise KeyError(robot_id)
        return StoredRobot(*row)

    def list_robots(self) -> list[StoredRobot]:
        """Every stored robot, oldest first."""
        with self._connect() as conn:
            rows = conn.execute(
                "SELECT id, model_json, created, description_json FROM robots ORDER BY rowid"
            ).fetchall()
        return [StoredRobot(*row) for row in rows]

    def robot_meshes(self, robot_id: str) -> dict[str, bytes]:
        """The mesh files stored with an imported robot, by key (empty for other robots)."""
        with self._connect() as conn:
            rows = conn.execute(
                "SELECT key, data FROM robot_meshes WHERE robot_id = ? ORDER BY key",
                (robot_id,),
            ).fetchall()
        return {key: bytes(data) for key, data in rows}

    def put_robot_file(self, robot_id: str, key: str, data: bytes) -> bool:
        """Store (or replace) a file kept with robot ``robot_id`` (e.g. its built collision
        model); False, and nothing written, when there is no such robot."""
        with self._connect() as conn:
            if conn.execute("SELECT 1 FROM robots WHERE id = ?", (robot_id,)).fetchone() is None:
                return False
            conn.execute("INSERT OR REPLACE INTO robot_meshes (robot_id, key, data) "
                         "VALUES (?, ?, ?)", (robot_id, key, data))
        return True

    def robot_file(self, robot_id: str, key: str) -> bytes | None:
        """One file kept with robot ``robot_id``; None if there is none."""
        with self._connect() as conn:
            row = conn.execute("SELECT data FROM robot_meshes WHERE robot_id = ? AND key = ?",
                               (robot_id, key)).fetchone()
        return None if row is None else bytes(row[0])

    def delete_robot(self, robot_id: str) -> bool:
        """Delete ``robot_id`` and its mesh files; whether there was such a row."""
        with self._connect() as conn:
            cur = conn.execute("DELETE FROM robots WHERE id = ?", (robot_id,))
            conn.execute("DELETE FROM robot_meshes WHERE robot_id = ?", (robot_id,))
        return cur.rowcount > 0

    # ---- scenes and meshes ----------------------------------------------------------------
    def put_scene(self, scene_id: str, scene_json: str) -> StoredScene:
        """Insert a scene; ``DuplicateError`` if ``scene_id`` is already stored."""
        created = now_iso()
        try:
            with self._connect() as conn:
                conn.execute("INSERT INTO scenes (id, scene_json, created) VALUES (?, ?, ?)",
                             (scene_id, scene_json, created))
        except sqlite3.IntegrityError:
            raise DuplicateError(scene_id) from None
        return StoredScene(scene_id, scene_json, created)

    def list_scenes(self) -> list[StoredScene]:
        """Every stored scene, oldest first."""
        with self._connect() as conn:
            rows = conn.execute(
                "SELECT id, scene_json, created FROM scenes ORDER BY rowid").fetchall()
        return [StoredScene(*row) for row in rows]

    def delete_scene(self, scene_id: str) -> bool:
        """Delete ``scene_id``; whether there was such a row."""
        with self._connect() as conn:
            cur = conn.execute("DELETE FROM scenes WHERE id = ?", (scene_id,))
        return cur.rowcount > 0

    def put_mesh(self, mesh_id: str, info_json: str, data: bytes) -> StoredMesh:
        """Insert a mesh file; ``DuplicateError`` if ``mesh_id`` is already stored."""
        created = now_iso()
        try:
            with self._connect() as conn:
                conn.execute(
                    "INSERT INTO meshes (id, info_json, data, created) VALUES (?, ?, ?, ?)",
                    (mesh_id, info_json, data, created))
        except sqlite3.IntegrityError:
            raise DuplicateError(mesh_id) from None
        return StoredMesh(mesh_id, info_json, created)

    def list_meshes(self) -> list[StoredMesh]:
        """Every stored mesh (without its data), oldest first."""
        with self._connect() as conn:
            rows = conn.execute(
                "SELECT id, info_json, created FROM meshes ORDER BY rowid").fetchall()
        return [StoredMesh(*row) for row in rows]

    def mesh_data(self, mesh_id: str) -> bytes:
        """The stored data of mesh ``mesh_id``; ``KeyError`` if there is none."""
        with self._connect() as conn:
            row = conn.execute("SELECT data FROM meshes WHERE id = ?", (mesh_id,)).fetchone()
        if row is None:
            raise KeyError(mesh_id)
        return bytes(row[0])

    def delete_mesh(self, mesh_id: str) -> bool:
        """Delete ``mesh_id``; whether there was such a row."""
        with self._connect() as conn:
            cur = conn.execute("DELETE FROM meshes WHERE id = ?", (mesh_id,))
        return cur.rowcount > 0

    # ---- jobs ---------------------------------------------------------------------------
    def add_job(self, job_id: str, kind: str, params: dict, payload: dict,
                max_queued: int | None = None, *,
                time_limit_s: float | None = None) -> JobRecord | None:
        """Queue a job; None (nothing written) when ``max_queued`` jobs are already queued."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            if max_queued is not None:
                (queued,) = conn.execute(
                    "SELECT COUNT(*) FROM jobs WHERE status = 'queued'").fetchone()
                if queued >= max_queued:
                    return None
            conn.execute(
                "INSERT INTO jobs (id, kind, params_json, payload_json, status, created, "
                "time_limit_s) VALUES (?, ?, ?, '', 'queued', ?, ?)",
                (job_id, kind, json.dumps(params), now_iso(), time_limit_s),
            )
            conn.execute("INSERT INTO job_payloads (job_id, payload_json) VALUES (?, ?)",
                         (job_id, json.dumps(payload)))
            # Read in the same transaction: the record as written, before a worker can
            # claim the job (the answer of POST /jobs is 'queued').
            row = conn.execute(f"SELECT {_JOB_COLUMNS} FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
        return _job(row)

    def get_job(self, job_id: str) -> JobRecord:
        """The job ``job_id``; KeyError if there is none."""
        with self._connect() as conn:
            row = conn.execute(f"SELECT {_JOB_COLUMNS} FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
        if row is None:
            raise KeyError(job_id)
        return _job(row)

    def list_jobs(self, status: str | None = None, limit: int | None = None, *,
                  kind: str | None = None, offset: int = 0) -> list[JobRecord]:
        """Jobs in submission order (optionally of one status and one kind), skipping the
        first ``offset`` of them, at most ``limit``."""
        where, args = _job_filter(status, kind)
        sql = f"SELECT {_JOB_COLUMNS} FROM jobs{where} ORDER BY seq"
        if limit is not None or offset:
            sql += " LIMIT ? OFFSET ?"
            args += (-1 if limit is None else int(limit), int(offset))
        with self._connect() as conn:
            return [_job(r) for r in conn.execute(sql, args).fetchall()]

    def latest_job_for_robot(self, kind: str, robot_id: str, status: str = "succeeded"
                             ) -> JobRecord | None:
        """The last submitted job of ``kind`` with ``status`` whose params name ``robot_id``
        as ``robot`` (exactly, no pattern); None if there is none. One look-up through the
        ``kind`` index, newest first, reading no job's result."""
        with self._connect() as conn:
            row = conn.execute(
                f"SELECT {_JOB_COLUMNS} FROM jobs WHERE kind = ? AND status = ? "
                "AND json_extract(params_json, '$.robot') = ? ORDER BY seq DESC LIMIT 1",
                (kind, status, robot_id)).fetchone()
        return None if row is None else _job(row)

    def job_payload(self, job_id: str) -> dict:
        """What the worker of a queued or running job gets; KeyError once the job has ended
        (its payload is dropped then) or if there is no such job."""
        with self._connect() as conn:
            row = conn.execute("SELECT payload_json FROM job_payloads WHERE job_id = ?",
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

    def count_attempt(self, job_id: str, message: str) -> None:
        """A running job (or a part of it) was started again: one more attempt."""
        with self._connect() as conn:
            conn.execute(
                "UPDATE jobs SET attempts = attempts + 1, message = ? "
                "WHERE id = ? AND status = 'running'", (message, job_id))

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
            if cur.rowcount > 0:
                conn.execute("DELETE FROM job_payloads WHERE job_id = ?", (job_id,))
        return cur.rowcount > 0

    def request_cancel(self, job_id: str) -> JobRecord:
        """Cancel a queued job at once; flag a running one for the backend to stop."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            if conn.execute(
                    "UPDATE jobs SET status = 'cancelled', finished = ?, message = 'cancelled' "
                    "WHERE id = ? AND status = 'queued'", (now_iso(), job_id)).rowcount:
                conn.execute("DELETE FROM job_payloads WHERE job_id = ?", (job_id,))
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
                (now_iso(), f"started {max_attempts} times without finishing (service restarts, "
                 "lost workers)",
                 "interrupted", max_attempts)).rowcount
            requeued = conn.execute(
                "UPDATE jobs SET status = 'queued', progress = 0, started = NULL, "
                "message = 're-queued after a service restart' WHERE status = 'running'"
            ).rowcount
            # A cancel asked for before the restart is honoured now.
            conn.execute(
                "UPDATE jobs SET status = 'cancelled', finished = ?, message = 'cancelled' "
                "WHERE status = 'queued' AND cancel_requested = 1", (now_iso(),))
            conn.execute(_DROP_ENDED_PAYLOADS)
        return requeued, failed

    def count_jobs(self, status: str | None = None, kind: str | None = None) -> int:
        """Jobs (optionally of one status and one kind)."""
        where, args = _job_filter(status, kind)
        with self._connect() as conn:
            return conn.execute(f"SELECT COUNT(*) FROM jobs{where}", args).fetchone()[0]

    def delete_ended_job(self, job_id: str) -> JobRecord | None:
        """Delete a job that has ended, with its result; its record as it was. None, and
        nothing deleted, while it is queued or running; KeyError if there is no such job."""
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            row = conn.execute(f"SELECT {_JOB_COLUMNS} FROM jobs WHERE id = ?",
                               (job_id,)).fetchone()
            if row is None:
                raise KeyError(job_id)
            job = _job(row)
            if job.status not in ENDED:
                return None
            conn.execute("DELETE FROM jobs WHERE id = ?", (job_id,))
            conn.execute("DELETE FROM job_payloads WHERE job_id = ?", (job_id,))
        return job

    def prune_jobs(self, *, finished_before: str | None = None, keep: int | None = None,
                   keep_latest: tuple[str, ...] = ()) -> int:
        """Delete ended jobs with their results: those that ended before ``finished_before``
        (a UTC ISO time, as ``now_iso``) and all but the ``keep`` that ended last. Queued and
        running jobs are never deleted, nor the latest succeeded job of each kind of
        ``keep_latest`` per robot (``params.robot``), which is not counted in ``keep``
        either. The number of jobs deleted."""
        spared, args = "", ()
        if keep_latest:
            # What the service still serves from (the learned IK of an ik_train job) stays.
            spared = (" AND seq NOT IN (SELECT MAX(seq) FROM jobs WHERE status = 'succeeded' "
                      f"AND kind IN ({', '.join('?' * len(keep_latest))}) "
                      "GROUP BY kind, json_extract(params_json, '$.robot'))")
            args = tuple(keep_latest)
        ended = f"status IN {_ENDED_SQL}{spared}"
        deleted = 0
        with self._connect() as conn:
            conn.execute("BEGIN IMMEDIATE")
            if finished_before is not None:
                deleted += conn.execute(f"DELETE FROM jobs WHERE {ended} AND finished < ?",
                                        (*args, finished_before)).rowcount
            if keep is not None:
                deleted += conn.execute(
                    f"DELETE FROM jobs WHERE seq IN (SELECT seq FROM jobs WHERE {ended} "
                    "ORDER BY finished DESC, seq DESC LIMIT -1 OFFSET ?)",
                    (*args, int(keep))).rowcount
            conn.execute(_DROP_ENDED_PAYLOADS)
        return deleted

    def compact(self, min_free_bytes: int = COMPACT_MIN_FREE_BYTES) -> int:
        """Give the database file's free pages (left by dropped payloads and deleted jobs)
        back to the file system once they add up to ``min_free_bytes``, and empty the
        write-ahead log; the bytes the store's files shrank by (0: nothing done). SQLite
        never shrinks a file by itself: a file made with incremental auto-vacuum (every store
        since payloads are dropped) moves its last pages into the free ones and is cut; an
        older file is rewritten once (VACUUM: a pause, and room for a copy of the live data,
        on the first compaction only)."""
        before = self.size_bytes()
        with self._connect() as conn:
            free = (conn.execute("PRAGMA freelist_count").fetchone()[0]
                    * conn.execute("PRAGMA page_size").fetchone()[0])
            if free == 0 or free < min_free_bytes:
                return 0
            if conn.execute("PRAGMA auto_vacuum").fetchone()[0] != 2:  # not incremental
                log.warning("rewriting the store at %s once (VACUUM) to give %.1f MB of free "
                            "pages back; later compactions are incremental", self.path,
                            free / 1e6)
                conn.execute("PRAGMA auto_vacuum = INCREMENTAL")
                conn.execute("VACUUM")
            else:
                # executescript steps the pragma to its end; execute() frees a single page.
                conn.executescript("PRAGMA incremental_vacuum;")
            conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
        return max(0, before - self.size_bytes())
