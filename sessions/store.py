"""A session: one folder holding ``session.sqlite`` (catalog, labels, history, model versions) and log arrays."""

from __future__ import annotations

import contextlib
import json
import shutil
import sqlite3
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import numpy as np

from . import labels as _labels
from .cameras import CameraStore
from .checks import CheckStore
from .disk_space import unusable_words
from .errors import LabelError, SessionError
from .ingest_lock import sweeping
from .label_files import LabelImport
from .log_files import checked_log_file
from .log_ingest import LOGS_DIR, LogIngest
from .logs import Channel, Gap, HistoryEntry, LogInfo, Segment
from .model_versions import CACHE_DIR, ModelRegistry
from .path_mcap import TerrainPath
from .pose_store import PoseStore
from .rowfiles import FileRows
from .schema import SCHEMA_VERSION, check_objects, migrate
from .session_copy import copy_session
from .terrain_rows import insert_terrain, renamed_to
from .terrain_store import TerrainStore

DB_NAME = "session.sqlite"
_STALE_TMP_S = 600.0  # leftovers older than this are from a crashed ingest, not one in progress


class Session(LogIngest, CameraStore, PoseStore, ModelRegistry, CheckStore, TerrainStore):
    """A session folder. Thread-safe: one SQLite connection guarded by a lock; every write is one transaction.

    Use :meth:`create` or :meth:`open`, not the constructor.
    """

    def __init__(self, path: Path, conn: sqlite3.Connection) -> None:
        self.path = path
        self._conn = conn
        self._lock = threading.RLock()
        self._arrays: dict[int, np.ndarray] = {}
        self._camera_index: dict[tuple[int, int], tuple[np.ndarray, Path]] = {}
        self._camera_lock = threading.Lock()
        self._inherited: sqlite3.Connection | None = None  # a forked child's copy of its parent's (after_fork)
        self._thumbs: OrderedDict[tuple[int, int, int, int], bytes] = OrderedDict()

    # ----------------------------------------------------------------------------------------------- lifecycle
    @classmethod
    def create(cls, path: str | Path) -> Session:
        """Create a new, empty session folder (the folder may exist if empty).

        Raises:
            SessionError: ``path`` is a file, a non-empty folder, or already a session.
        """
        path = Path(path)
        if (path / DB_NAME).exists():
            raise SessionError(f"{path}: already a session; open it instead")
        if path.exists() and (not path.is_dir() or any(path.iterdir())):
            raise SessionError(f"{path}: exists and is not an empty folder")
        try:
            (path / LOGS_DIR).mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SessionError(f"{path}: cannot create session folder: {exc.strerror or exc}") from None
        return cls._connect(path)

    @classmethod
    def open(cls, path: str | Path) -> Session:
        """Open an existing session, migrating its schema forward if it is older.

        Raises:
            SessionError: Not a session, damaged, or written by a newer workbench.
        """
        path = Path(path)
        if not (path / DB_NAME).is_file():
            raise SessionError(f"{path}: not a session folder (no {DB_NAME}); create one with `workbench new {path}`")
        return cls._connect(path)

    @staticmethod
    def _new_connection(path: Path) -> sqlite3.Connection:
        conn = sqlite3.connect(path / DB_NAME, isolation_level=None, check_same_thread=False, timeout=30.0)
        try:
            conn.execute("PRAGMA journal_mode = WAL")
            # FULL: an acknowledged label survives power loss, not only a killed process.
            conn.execute("PRAGMA synchronous = FULL")
            conn.execute("PRAGMA foreign_keys = ON")
        except BaseException:
            conn.close()
            raise
        return conn

    @classmethod
    def _connect(cls, path: Path) -> Session:
        try:
            conn = cls._new_connection(path)
            try:
                migrate(conn, where=str(path))
                check_objects(conn, where=str(path / DB_NAME))
            except BaseException:
                conn.close()
                raise
        except sqlite3.DatabaseError as exc:
            raise SessionError(unusable_words(path, path / DB_NAME, exc)) from None
        session = cls(path, conn)
        (path / LOGS_DIR).mkdir(exist_ok=True)
        session._sweep_leftovers()
        return session

    @contextlib.contextmanager
    def fork_guard(self) -> Iterator[None]:
        """Hold this session's lock: no other thread is inside a query on its connection while a process is forked
        within (a child forked mid-query would start with SQLite's state half-used)."""
        with self._lock:
            yield

    def after_fork(self) -> None:
        """In a process forked while this session was open: a connection and locks of its own.

        A SQLite connection must not be used on both sides of a fork, and a lock another thread held at the fork
        stays held in the child. The inherited connection is kept unused and never closed here: closing it in the
        child could checkpoint and remove the write-ahead log the parent still uses. Fork under :meth:`fork_guard`.

        Raises:
            SessionError: The database cannot be opened again.
        """
        self._inherited = self._conn  # kept referenced: collecting it would close it
        self._lock = threading.RLock()
        self._camera_lock = threading.Lock()
        try:
            self._conn = self._new_connection(self.path)
        except sqlite3.DatabaseError as exc:
            raise SessionError(f"{self.path / DB_NAME}: cannot be opened again in a forked process ({exc})") from None

    def close(self) -> None:
        with self._lock:
            self._arrays.clear()
            self._conn.close()

    def __enter__(self) -> Session:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def copy_to(self, dest: str | Path) -> Path:
        """A copy of the whole session in the new folder ``dest`` (``session_copy.copy_session``), for work that must
        leave this one as it is (an evaluation that labels and trains).

        Raises:
            SessionError: ``dest`` exists, or the copy failed (nothing is left at ``dest``).
        """
        with self._lock:
            return copy_session(self.path, self._conn, Path(dest))

    @property
    def schema_version(self) -> int:
        return SCHEMA_VERSION

    @contextlib.contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction; committed when the block ends, rolled back on any error."""
        with self._lock:
            try:
                self._conn.execute("BEGIN IMMEDIATE")
                try:
                    yield self._conn
                    self._conn.execute("COMMIT")
                except BaseException:
                    if self._conn.in_transaction:  # SQLite rolls back by itself on some errors (a full disk)
                        self._conn.execute("ROLLBACK")
                    raise
            except sqlite3.OperationalError as exc:
                # disk full, read-only folder or file, I/O error, locked past the timeout: nothing was changed
                raise SessionError(f"{self.path}: cannot save to the session ({exc}); nothing was changed") from None

    def _read(self, query: str, args: Sequence[object] = ()) -> list[tuple]:
        with self._lock:
            return self._conn.execute(query, args).fetchall()

    def _sweep_leftovers(self) -> None:
        """Remove what crashed ingests and model saves left: files and folders no catalog row points to."""
        known = {r[0] for r in self._read("SELECT file FROM logs")}
        cutoff = time.time() - _STALE_TMP_S
        with sweeping(self.path / LOGS_DIR) as no_ingest_running:
            # with no ingest running, every staged file is a dead one's; else only old ones are
            logs_cutoff = float("inf") if no_ingest_running else cutoff
            for f in (self.path / LOGS_DIR).glob(".tmp-*"):  # staged arrays and camera files of a crashed ingest
                with contextlib.suppress(OSError):
                    if f.stat().st_mtime < logs_cutoff:
                        f.unlink()
            for f in (self.path / LOGS_DIR).glob("*.npy"):
                rel = f"{LOGS_DIR}/{f.name}"
                with contextlib.suppress(OSError):
                    if rel not in known and f.stat().st_mtime < logs_cutoff:
                        f.unlink()
        # Model versions: a folder no catalog row points to is a save that died before it was registered.
        models = self.path / "models"
        registered = {r[0] for r in self._read("SELECT path FROM model_versions")}
        for d in models.iterdir() if models.is_dir() else ():
            if f"models/{d.name}" not in registered and d.is_dir() and d.stat().st_mtime < cutoff:
                shutil.rmtree(d, ignore_errors=True)
        # Derived-data caches: a pass that died mid-write leaves its staged ".name.tag.npy" files.
        cache = self.path / CACHE_DIR
        for f in cache.glob("*/.*.npy") if cache.is_dir() else ():
            if f.stat().st_mtime < cutoff:
                with contextlib.suppress(OSError):
                    f.unlink()

    # ------------------------------------------------------------------------------------------------- catalog
    def logs(self) -> list[LogInfo]:
        """All logs, in ingest order."""
        return [self._log_info(row) for row in self._read(f"SELECT {_LOG_COLS} FROM logs ORDER BY id")]

    def log(self, log_id: int) -> LogInfo:
        """One log by id.

        Raises:
            SessionError: No such log.
        """
        rows = self._read(f"SELECT {_LOG_COLS} FROM logs WHERE id = ?", (log_id,))
        if not rows:
            raise SessionError(f"{self.path}: no log with id {log_id}")
        return self._log_info(rows[0])

    def _log_info(self, row: tuple) -> LogInfo:
        log_id = int(row[0])
        channels = tuple(
            Channel(*r)
            for r in self._read("SELECT name, unit, source FROM channels WHERE log_id = ? ORDER BY idx", (log_id,))
        )
        gaps = tuple(
            Gap(*r)
            for r in self._read(
                "SELECT start, stop, stream, reason FROM gaps WHERE log_id = ? ORDER BY start", (log_id,)
            )
        )
        return LogInfo(
            id=log_id,
            name=row[1],
            source_path=row[2],
            format=row[3],
            file=row[4],
            n_samples=int(row[5]),
            rate_hz=float(row[6]),
            t0=float(row[7]),
            channels=channels,
            gaps=gaps,
            reference_terrain=row[8],
            ingested_at=row[9],
            info=json.loads(row[10]),
        )

    def array(self, log_id: int) -> np.ndarray:
        """The whole ``(T, C)`` float32 array of a log, memory-mapped read-only (nothing is read until sliced)."""
        with self._lock:
            arr = self._arrays.get(log_id)
            if arr is None:
                path, _ = checked_log_file(self.path, self.log(log_id))
                arr = self._arrays[log_id] = np.load(path, mmap_mode="r", allow_pickle=False)
            return arr

    def rows(self, log_id: int) -> FileRows:
        """The ``(T, C)`` float32 array of a log as rows read on demand (``rows[a:b]``), without a memory map.

        For passes over whole long logs: what a map has read stays in the process's resident memory, these reads do
        not.
        """
        path, _ = checked_log_file(self.path, self.log(log_id))
        return FileRows.open_npy(path)

    def samples(self, log_id: int, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Samples ``[start, stop)`` of a log as a ``(stop - start, C)`` float32 array; reads only that slice."""
        return np.array(self.array(log_id)[start:stop])

    def reference(self, log_id: int) -> list[tuple[int, int, str]]:
        """Reference truth of a log as ``(start, stop, terrain)`` in samples: for evaluation, never labels."""
        return [
            (int(a), int(b), str(t))
            for a, b, t in self._read(
                "SELECT start, stop, terrain FROM reference WHERE log_id = ? ORDER BY start", (log_id,)
            )
        ]

    # -------------------------------------------------------------------------------------------------- labels
    def add_segment(
        self, log_id: int, start: int, stop: int, terrain: str, *, author: str, source: str = "manual"
    ) -> Segment:
        """Label samples ``[start, stop)`` of a log; merges with same-terrain segments it overlaps or touches.

        Raises:
            LabelError: Bad range, unknown log or terrain, or overlap with another terrain's segment.
        """
        with self._write() as conn:
            return _labels.add_segment(
                conn, log_id=log_id, start=start, stop=stop, terrain=terrain, author=author, source=source
            )

    def add_segments(
        self, log_id: int, ranges: Sequence[tuple[int, int]], terrain: str, *, author: str, source: str
    ) -> list[Segment]:
        """Label several ranges of a log with one terrain as one action: one undo reverts them all (accepting a
        model's stretch around labels already there).

        Raises:
            LabelError: A bad range, unknown log or terrain, or overlap with another terrain's segment; nothing is
                saved then.
        """
        with self._write() as conn:
            return _labels.add_segments(
                conn, log_id=log_id, ranges=ranges, terrain=terrain, author=author, source=source
            )

    def change_segment(
        self,
        segment_id: int,
        *,
        author: str,
        start: int | None = None,
        stop: int | None = None,
        terrain: str | None = None,
    ) -> Segment:
        """Move, resize or relabel a segment (same rules as :meth:`add_segment`)."""
        with self._write() as conn:
            return _labels.change_segment(conn, segment_id, author=author, start=start, stop=stop, terrain=terrain)

    def delete_segment(self, segment_id: int, *, author: str) -> Segment:
        """Delete a segment; returns it as it was."""
        with self._write() as conn:
            return _labels.delete_segment(conn, segment_id, author=author)

    def undo(self, *, author: str, only_author: bool = True) -> HistoryEntry:
        """Undo the latest label action (of ``author`` unless ``only_author`` is False).

        Raises:
            LabelError: Nothing to undo, or a later action changed the same segments.
        """
        with self._write() as conn:
            return _labels.undo(conn, author=author, only_author=only_author)

    def segments(self, log_id: int | None = None) -> list[Segment]:
        """Label segments, of one log or all."""
        with self._lock:
            return _labels.list_segments(self._conn, log_id=log_id)

    def segment(self, segment_id: int) -> Segment:
        """One segment by id."""
        with self._lock:
            return _labels.get_segment(self._conn, segment_id)

    def export_labels(self, path: str | Path) -> Path:
        """Write every segment to a CSV, Parquet or JSON file (by suffix)."""
        from .label_files import segments_frame, write_frame

        logs = {x.id: x for x in self.logs()}
        return write_frame(segments_frame(self.segments(), logs), Path(path))

    def export_label_studio(self, path: str | Path, *, url_prefix: str | None = None) -> list[Path]:
        """Write Label Studio's time-series import: one task per log with its labels as regions (``label_studio``).

        Args:
            path: The tasks JSON; the logs' CSVs and the labeling config go to the folder beside it (``NAME-files``).
            url_prefix: What goes before a CSV's name in a task (default: Label Studio's local-files URL).

        Returns:
            The files written.
        """
        from .label_studio import write_label_studio

        def samples(log: LogInfo, start: int, stop: int) -> np.ndarray:
            return self.samples(log.id, start, stop)

        return write_label_studio(
            Path(path), self.logs(), self.segments(), self.terrains(), samples, url_prefix=url_prefix
        )

    def export_labels_mcap(
        self, path: str | Path, *, drawn: Callable[[LogInfo], TerrainPath | None] | None = None
    ) -> list[tuple[Path, LogInfo]]:
        """Write each labelled log's segments to an MCAP file of its own, on the log's clock (``terrain_mcap``).

        Args:
            path: The file for one labelled log; for several, each log's name goes before ``.mcap``.
            drawn: A log's path coloured by terrain, where it has one, for Foxglove's 3D and Map panels.

        Returns:
            The files written and their logs, none when nothing is labelled.

        Raises:
            WorkbenchError: One of the files exists (checked before any is written).
        """
        from .terrain_mcap import LogClock, per_log_paths, refuse_existing, write_terrain_mcap

        segments = self.segments()
        logs = [x for x in self.logs() if any(s.log_id == x.id for s in segments)]
        paths = per_log_paths(Path(path), [x.name for x in logs])
        refuse_existing(paths)
        for log, out in zip(logs, paths, strict=True):
            mine = [s for s in segments if s.log_id == log.id]
            write_terrain_mcap(
                out,
                LogClock.of(log),
                labels=mine,
                about={"source_file": log.source_path, "session": self.path.name},
                path_drawn=None if drawn is None else drawn(log),
            )
        return list(zip(paths, logs, strict=True))

    def import_labels(self, path: str | Path, *, author: str, create_terrains: bool = False) -> LabelImport:
        """Import a label file in one transaction: every row, or none when any row is refused.

        Args:
            path: A .csv, .parquet or .json label file.
            author: Author of rows that name none.
            create_terrains: Add the terrains the file names that the session lacks (in the same transaction:
                a refused file adds none).

        Returns:
            What it did: the segments stored, the rows already labelled so, the rows left out because their terrain
            is empty (a row of ``workbench suggest``'s file nobody labelled), the checks added and those kept before.

        Raises:
            LabelError: Unreadable file, missing columns, unknown logs or terrains, overlaps, or a suggestion file's
                row naming a classifier version or check kind the session does not have.
        """
        from dataclasses import replace

        from .label_files import import_rows, read_frame, unlabelled_rows
        from .row_names import names_as_written

        path = Path(path)
        logs = self.logs()
        frame, empty = unlabelled_rows(read_frame(path, logs=logs))
        with self._write() as conn:
            frame = names_as_written(conn, frame)  # a row written before a rename names the terrain it meant
            terrains = self._terrains_for(conn, frame, create_terrains)
            return replace(import_rows(conn, frame, logs, terrains, path=path, author=author), blank=tuple(empty))

    def _terrains_for(self, conn, frame, create: bool) -> list[str]:
        """The session's terrain names, with those ``frame`` names added first when ``create``."""
        names = [r[0] for r in conn.execute("SELECT name FROM terrains ORDER BY position")]
        if create and "terrain" in frame.columns:
            gave_up = renamed_to(conn)
            for name in dict.fromkeys(str(t).strip() for t in frame["terrain"].dropna()):
                if name in gave_up:  # not a new terrain: the old name of one (a second `dirt` beside `soil`)
                    raise LabelError(
                        f"terrain {name!r} was renamed {gave_up[name]!r} in this session: --create-terrains makes "
                        "no second one; write its name now in the file (nothing was imported)"
                    )
                if name and name not in names:
                    insert_terrain(conn, name, None)
                    names.append(name)
        return names

    def import_reference(self, path: str | Path, *, create_terrains: bool = False) -> int:
        """Reference truth from a label file, for evaluation only: it replaces the reference of every log the file
        names, in one transaction, and never becomes labels. Returns the rows read.

        Raises:
            LabelError: Unreadable file, missing columns, unknown logs or terrains, bad cells, overlapping rows.
        """
        from .label_files import import_reference_rows, read_frame

        path = Path(path)
        logs = self.logs()
        frame = read_frame(path, logs=logs)
        with self._write() as conn:
            terrains = self._terrains_for(conn, frame, create_terrains)
            return import_reference_rows(conn, frame, logs, terrains, path=path)

    def history(self, *, limit: int | None = None) -> list[HistoryEntry]:
        """Label actions, newest first."""
        with self._lock:
            return _labels.history(self._conn, limit=limit)


_LOG_COLS = "id, name, source_path, format, file, n_samples, rate_hz, t0, reference_terrain, ingested_at, info"
