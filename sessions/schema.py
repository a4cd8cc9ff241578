"""The SQLite schema of a session and its forward migrations.

The schema version lives in ``PRAGMA user_version``. ``MIGRATIONS[i]`` moves a database from version ``i`` to
``i + 1``; a session is migrated forward when opened, inside one transaction, and refused when it comes from a
newer workbench than this one.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable, Sequence

from .errors import SessionError

Migration = Callable[[sqlite3.Connection], None]

# Colours for terrains people often name, used when one of these is added (a new session has no terrains: they come
# from the person, their label files or reference names, not from a dataset we once read)
KNOWN_TERRAIN_COLORS: dict[str, str] = {
    "concrete": "#9e9e9e",
    "grass": "#4caf50",
    "gravel": "#795548",
    "mulch": "#ff9800",
    "dirt": "#8d6e63",
    "sand": "#fdd835",
}


def _run_script(conn: sqlite3.Connection, script: str) -> None:
    # Not executescript(): it commits the open transaction first, and a migration must be all-or-nothing.
    for statement in script.split(";"):
        if statement.strip():
            conn.execute(statement)


def _v1(conn: sqlite3.Connection) -> None:
    _run_script(
        conn,
        """
        CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);

        CREATE TABLE logs (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            name TEXT NOT NULL,
            source_path TEXT NOT NULL,
            source_sha256 TEXT NOT NULL,
            format TEXT NOT NULL,
            file TEXT NOT NULL UNIQUE,
            n_samples INTEGER NOT NULL,
            rate_hz REAL NOT NULL,
            t0 REAL NOT NULL,
            reference_terrain TEXT,
            info TEXT NOT NULL DEFAULT '{}',
            ingested_at TEXT NOT NULL
        );
        CREATE UNIQUE INDEX logs_source ON logs (source_sha256, name);

        CREATE TABLE channels (
            log_id INTEGER NOT NULL REFERENCES logs (id) ON DELETE CASCADE,
            idx INTEGER NOT NULL,
            name TEXT NOT NULL,
            unit TEXT NOT NULL,
            source TEXT NOT NULL,
            PRIMARY KEY (log_id, idx)
        );

        CREATE TABLE gaps (
            log_id INTEGER NOT NULL REFERENCES logs (id) ON DELETE CASCADE,
            start INTEGER NOT NULL,
            stop INTEGER NOT NULL,
            stream TEXT NOT NULL,
            reason TEXT NOT NULL
        );

        -- Reference truth from the source (file names, demo sidecars): for evaluation only, never labels.
        CREATE TABLE reference (
            log_id INTEGER NOT NULL REFERENCES logs (id) ON DELETE CASCADE,
            start INTEGER NOT NULL,
            stop INTEGER NOT NULL,
            terrain TEXT NOT NULL
        );

        CREATE TABLE terrains (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            name TEXT NOT NULL UNIQUE,
            color TEXT NOT NULL,
            position INTEGER NOT NULL
        );

        CREATE TABLE segments (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            log_id INTEGER NOT NULL REFERENCES logs (id),
            start INTEGER NOT NULL,
            stop INTEGER NOT NULL,
            terrain_id INTEGER NOT NULL REFERENCES terrains (id),
            author TEXT NOT NULL,
            source TEXT NOT NULL,
            created_at TEXT NOT NULL,
            updated_at TEXT NOT NULL,
            CHECK (stop > start AND start >= 0)
        );
        CREATE INDEX segments_log ON segments (log_id, start);

        -- One row per user action, and label_history holds the segment rows it changed (before/after as JSON).
        CREATE TABLE label_ops (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            at TEXT NOT NULL,
            author TEXT NOT NULL,
            kind TEXT NOT NULL,
            undone_by INTEGER REFERENCES label_ops (id),
            undoes INTEGER REFERENCES label_ops (id)
        );
        CREATE TABLE label_history (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            op_id INTEGER NOT NULL REFERENCES label_ops (id),
            segment_id INTEGER NOT NULL,
            before TEXT,
            after TEXT
        );
        CREATE INDEX label_history_op ON label_history (op_id);

        CREATE TABLE model_versions (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            stage TEXT NOT NULL,
            path TEXT NOT NULL,
            created_at TEXT NOT NULL,
            config TEXT NOT NULL DEFAULT '{}',
            metrics TEXT NOT NULL DEFAULT '{}',
            active INTEGER NOT NULL DEFAULT 0
        );

        CREATE TABLE runs (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            kind TEXT NOT NULL,
            status TEXT NOT NULL,
            started_at TEXT NOT NULL,
            ended_at TEXT,
            params TEXT NOT NULL DEFAULT '{}',
            result TEXT NOT NULL DEFAULT '{}'
        );
        """,
    )


def _v2(conn: sqlite3.Connection) -> None:
    """The person's checks (``checks.py``): what the model said where a label was made, before it trained on it."""
    _run_script(
        conn,
        """
        CREATE TABLE checks (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            log_id INTEGER NOT NULL REFERENCES logs (id) ON DELETE CASCADE,
            start INTEGER NOT NULL,
            stop INTEGER NOT NULL,
            terrain TEXT NOT NULL,
            predicted TEXT NOT NULL,
            agreement REAL NOT NULL,
            classifier INTEGER NOT NULL,
            kind TEXT NOT NULL,
            author TEXT NOT NULL,
            at TEXT NOT NULL,
            CHECK (stop > start AND start >= 0 AND agreement >= 0 AND agreement <= 1)
        );
        CREATE INDEX checks_log ON checks (log_id, start)
        """,
    )


def _v3(conn: sqlite3.Connection) -> None:
    """A piece checks a model once: one check per (log, span, classifier version, kind), the copies an import made
    again dropped (the first kept); and the terrains' renames, so a name a model or a file used then is found now."""
    _run_script(
        conn,
        """
        DELETE FROM checks WHERE id NOT IN (
            SELECT MIN(id) FROM checks GROUP BY log_id, start, stop, classifier, kind
        );
        CREATE UNIQUE INDEX checks_once ON checks (log_id, start, stop, classifier, kind);
        CREATE TABLE terrain_renames (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            terrain_id INTEGER NOT NULL,
            old TEXT NOT NULL,
            new TEXT NOT NULL,
            at TEXT NOT NULL
        )
        """,
    )


def _v4(conn: sqlite3.Connection) -> None:
    """The checks the session drew and wrote (a ``suggest`` file's rows): a filled-in row is a check of the kind the
    session drew there and of the guess its classifier made, whatever the file's own columns say."""
    _run_script(
        conn,
        """
        CREATE TABLE issued (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            log_id INTEGER NOT NULL REFERENCES logs (id) ON DELETE CASCADE,
            start INTEGER NOT NULL,
            stop INTEGER NOT NULL,
            classifier INTEGER NOT NULL,
            kind TEXT NOT NULL,
            guess TEXT,
            at TEXT NOT NULL
        );
        CREATE UNIQUE INDEX issued_once ON issued (log_id, start, stop, classifier)
        """,
    )


MIGRATIONS: tuple[Migration, ...] = (_v1, _v2, _v3, _v4)
SCHEMA_VERSION = len(MIGRATIONS)


def schema_version(conn: sqlite3.Connection) -> int:
    """The schema version stored in the database (0 for an empty one)."""
    return int(conn.execute("PRAGMA user_version").fetchone()[0])


def migrate(conn: sqlite3.Connection, *, migrations: Sequence[Migration] = MIGRATIONS, where: str = "") -> int:
    """Bring ``conn`` forward to ``len(migrations)``, all steps in one transaction.

    Args:
        conn: A connection in autocommit mode (``isolation_level=None``).
        migrations: The migration steps; tests pass their own to exercise the mechanism.
        where: The session path, for error messages.

    Returns:
        The schema version after migrating.

    Raises:
        SessionError: The database was written by a newer workbench.
    """
    target = len(migrations)
    current = schema_version(conn)
    if current > target:
        raise SessionError(
            f"{where}: session schema version {current} is newer than this workbench supports ({target}); "
            "upgrade the workbench to open it"
        )
    if current == target:
        return current
    conn.execute("BEGIN IMMEDIATE")
    try:
        # Re-read inside the write lock: another process may have migrated meanwhile.
        current = schema_version(conn)
        for step in migrations[current:]:
            step(conn)
        conn.execute(f"PRAGMA user_version = {target}")
        conn.execute("COMMIT")
    except BaseException:
        conn.execute("ROLLBACK")
        raise
    return target


_EXPECTED: dict[str, str] | None = None


def _expected_objects() -> dict[str, str]:
    """Name -> type of every object a session's database holds at this schema version, from a fresh one."""
    global _EXPECTED
    if _EXPECTED is None:
        fresh = sqlite3.connect(":memory:", isolation_level=None)
        try:
            migrate(fresh)
            _EXPECTED = dict(fresh.execute("SELECT name, type FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'"))
        finally:
            fresh.close()
    return _EXPECTED


def check_objects(conn: sqlite3.Connection, *, where: str) -> None:
    """Refuse a database whose tables are not what the workbench writes: a table replaced by a view (a recursive
    view named ``logs`` made ``info`` allocate 8 GB), or a view or trigger of someone else's, runs their SQL on every
    read. Only the catalog is read, so this costs a millisecond whatever the session's size.

    Raises:
        SessionError: A table is missing, or is a view, or the file holds views or triggers.
    """
    expected = _expected_objects()
    found = dict(conn.execute("SELECT name, type FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'"))
    for name, kind in found.items():
        if expected.get(name) != kind and kind in ("view", "trigger"):
            what = f"a {kind} where the workbench keeps a {expected[name]}" if name in expected else f"a {kind}"
            raise SessionError(
                f"{where}: {name!r} is {what}: this database was changed outside the workbench; restore "
                "session.sqlite from a backup"
            )
    missing = [n for n, kind in expected.items() if kind == "table" and found.get(n) != "table"]
    if missing:
        raise SessionError(f"{where}: table {missing[0]!r} is missing: not a session database the workbench wrote")
