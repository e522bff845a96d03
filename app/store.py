"""The service's SQLite store (``<data_dir>/kinoplan.sqlite3``): custom robots, later jobs.

One file holds every table; ``PRAGMA user_version`` records which of ``_MIGRATIONS`` have
run, so a later table (jobs) is one more entry there. The store is called from FastAPI's
thread pool: every call opens its own connection (cheap for a local file) and runs in one
transaction, so a crash never leaves half a write, and WAL mode lets readers proceed while
one writer commits.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

__all__ = ["Store", "StoredRobot", "DuplicateError", "STORE_FILENAME"]

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
)


class DuplicateError(Exception):
    """A row with this id already exists."""


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
                conn.execute(_MIGRATIONS[k])
            if version < len(_MIGRATIONS):
                conn.execute(f"PRAGMA user_version = {len(_MIGRATIONS)}")

    # ---- robots -------------------------------------------------------------------------
    def put_robot(self, robot_id: str, model_json: str) -> StoredRobot:
        """Insert a robot; ``DuplicateError`` if ``robot_id`` is already stored."""
        created = datetime.now(UTC).isoformat(timespec="microseconds")
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
