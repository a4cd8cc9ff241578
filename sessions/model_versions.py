"""The model-version registry and training-run records of a session.

A version's files live in ``SESSION/models/vNNNN/`` (written elsewhere under a temporary name and renamed in before
the version is registered); the catalog row points at it. Exactly one version per stage is active.
"""

from __future__ import annotations

import json
import sqlite3
import threading
from dataclasses import dataclass
from pathlib import Path

from .errors import SessionError
from .labels import now

MODELS_DIR = "models"
CACHE_DIR = "cache"


@dataclass(frozen=True)
class ModelVersion:
    """A trained model in the session."""

    id: int
    stage: str  # "predictor" | "classifier"
    path: str  # relative to the session folder
    created_at: str
    config: dict
    metrics: dict
    active: bool


def _version(row: tuple) -> ModelVersion:
    return ModelVersion(int(row[0]), row[1], row[2], row[3], json.loads(row[4]), json.loads(row[5]), bool(row[6]))


_COLS = "id, stage, path, created_at, config, metrics, active"


def next_version_id(conn: sqlite3.Connection) -> int:
    row = conn.execute("SELECT seq FROM sqlite_sequence WHERE name = 'model_versions'").fetchone()
    return (int(row[0]) if row else 0) + 1


def register(
    conn: sqlite3.Connection, *, stage: str, path: str, config: dict, metrics: dict, activate: bool = True
) -> ModelVersion:
    """Add a version (its files already in place) and make it the active one of its stage."""
    cur = conn.execute(
        "INSERT INTO model_versions (stage, path, created_at, config, metrics, active) VALUES (?, ?, ?, ?, ?, 0)",
        (stage, path, now(), json.dumps(config), json.dumps(metrics)),
    )
    version_id = int(cur.lastrowid)
    if activate:
        activate_version(conn, version_id)
    return get(conn, version_id)


def activate_version(conn: sqlite3.Connection, version_id: int) -> None:
    row = conn.execute("SELECT stage FROM model_versions WHERE id = ?", (version_id,)).fetchone()
    if row is None:
        raise SessionError(f"no model version {version_id}")
    conn.execute("UPDATE model_versions SET active = 0 WHERE stage = ?", (row[0],))
    conn.execute("UPDATE model_versions SET active = 1 WHERE id = ?", (version_id,))


def get(conn: sqlite3.Connection, version_id: int) -> ModelVersion:
    row = conn.execute(f"SELECT {_COLS} FROM model_versions WHERE id = ?", (version_id,)).fetchone()
    if row is None:
        raise SessionError(f"no model version {version_id}")
    return _version(row)


def versions(conn: sqlite3.Connection, stage: str | None = None) -> list[ModelVersion]:
    query = f"SELECT {_COLS} FROM model_versions"
    args: tuple = ()
    if stage:
        query += " WHERE stage = ?"
        args = (stage,)
    return [_version(r) for r in conn.execute(query + " ORDER BY id", args).fetchall()]


def active(conn: sqlite3.Connection, stage: str) -> ModelVersion | None:
    row = conn.execute(f"SELECT {_COLS} FROM model_versions WHERE stage = ? AND active = 1", (stage,)).fetchone()
    return None if row is None else _version(row)


def start_run(conn: sqlite3.Connection, kind: str, params: dict) -> int:
    cur = conn.execute(
        "INSERT INTO runs (kind, status, started_at, params) VALUES (?, 'running', ?, ?)",
        (kind, now(), json.dumps(params)),
    )
    return int(cur.lastrowid)


def finish_run(conn: sqlite3.Connection, run_id: int, status: str, result: dict) -> None:
    conn.execute(
        "UPDATE runs SET status = ?, ended_at = ?, result = ? WHERE id = ?", (status, now(), json.dumps(result), run_id)
    )


class ModelRegistry:
    """The model-version part of :class:`sessions.Session` (a mixin over its connection, lock and path)."""

    path: Path
    _conn: sqlite3.Connection
    _lock: threading.RLock

    _write: object  # Session's write-transaction context manager

    def models_dir(self) -> Path:
        """Where model versions live (``SESSION/models``)."""
        d = self.path / MODELS_DIR
        d.mkdir(exist_ok=True)
        return d

    def cache_dir(self, name: str) -> Path:
        """A folder for derived data that can always be recomputed (``SESSION/cache/NAME``)."""
        d = self.path / CACHE_DIR / name
        d.mkdir(parents=True, exist_ok=True)
        return d

    def next_model_dir(self) -> Path:
        """The folder the next model version would get (not created)."""
        with self._lock:
            return self.models_dir() / f"v{next_version_id(self._conn):04d}"

    def register_model(
        self, stage: str, path: Path, *, config: dict, metrics: dict, activate: bool = True
    ) -> ModelVersion:
        """Record a model version whose files are complete at ``path`` (inside the session folder)."""
        rel = str(Path(path).resolve().relative_to(self.path.resolve()))
        with self._write() as conn:
            return register(conn, stage=stage, path=rel, config=config, metrics=metrics, activate=activate)

    def model_versions(self, stage: str | None = None) -> list[ModelVersion]:
        """Model versions, oldest first."""
        with self._lock:
            return versions(self._conn, stage)

    def active_model(self, stage: str) -> ModelVersion | None:
        """The active version of ``stage`` ("predictor" or "classifier"), if any."""
        with self._lock:
            return active(self._conn, stage)

    def activate_model(self, version_id: int) -> None:
        """Make a version the active one of its stage again."""
        with self._write() as conn:
            activate_version(conn, version_id)

    def start_run(self, kind: str, params: dict) -> int:
        """Record that a training run started; returns its id."""
        with self._write() as conn:
            return start_run(conn, kind, params)

    def finish_run(self, run_id: int, status: str, result: dict | None = None) -> None:
        """Record how a training run ended ("done", "cancelled", "failed")."""
        with self._write() as conn:
            finish_run(conn, run_id, status, result or {})
