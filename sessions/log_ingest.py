"""The ingest part of :class:`sessions.Session`: log files read, aligned and stored as arrays in the session.

Each source is all-or-nothing: aligned rows go to staged files in the logs folder as they are computed, and a log is
listed only once its array is synced and renamed into place in the same transaction that records it.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import os
import sqlite3
import threading
import uuid
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from . import labels as _labels
from .cameras import place_cameras, stage_cameras
from .errors import IngestError, SessionError
from .ingest import AlignedLog, IngestOptions, ParsedLog, align, plan_sources, read_source
from .ingest.sources import Source
from .ingest_lock import ingesting
from .logs import LogInfo
from .pose_store import place_poses, stage_poses
from .rowfiles import NpyWriter

LOGS_DIR = "logs"


def _sha256(files: Sequence[str | Path]) -> str:
    h = hashlib.sha256()
    for f in files:
        with open(f, "rb") as fh:
            for block in iter(lambda fh=fh: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def fsync_dir(path: Path) -> None:
    """Make a folder's entries (renames, new files) durable."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


class LogIngest:
    """Ingest for :class:`sessions.Session` (a mixin over its connection, lock and path)."""

    path: Path
    _conn: sqlite3.Connection
    _lock: threading.RLock

    # Session's write transaction, reads and catalog, which this part uses
    _write: Callable[[], contextlib.AbstractContextManager[sqlite3.Connection]]
    _read: Callable[..., list[tuple]]
    log: Callable[[int], LogInfo]

    def ingest(
        self,
        paths: Sequence[str | Path],
        *,
        options: IngestOptions | None = None,
        on_error: Callable[[IngestError], None] | None = None,
        progress: Callable[[int, int], None] | None = None,
    ) -> list[LogInfo]:
        """Ingest log files (or folders of them). Each source is all-or-nothing.

        Args:
            paths: MCAP / CSV files or folders holding them.
            options: How to read and align.
            on_error: Called with each refused file, and ingest goes on; without it the first error is raised.
            progress: Called now and then with (bytes read, bytes in all sources), for a progress bar.

        Returns:
            The logs of the given paths: newly ingested ones, and ones already in the session (same content).
        """
        options = options or IngestOptions()
        sources, errors = plan_sources(list(paths))

        def fail(err: IngestError) -> None:
            if on_error is None:
                raise err
            on_error(err)

        for err in errors:
            fail(err)
        with ingesting(self.path / LOGS_DIR):  # the sweep of another process leaves this one's staged files alone
            return self._ingest_sources(sources, options, fail, progress)

    def logs_recorded_in(self, files: Sequence[str | Path]) -> dict[Path, list[LogInfo]]:
        """Per file given (as ``ingest`` groups them into sources), the session's logs read from a recording of the
        same content under any name: a copy or a link of a log's file is that log, whatever it is called.

        Raises:
            IngestError: A file cannot be read.
        """
        sources, _ = plan_sources(list(files))
        out: dict[Path, list[LogInfo]] = {}
        for src in sources:
            try:
                sha = _sha256(src.files)
            except OSError as exc:
                raise IngestError(src.files[0], f"cannot read: {exc.strerror or exc}") from None
            ids = [int(r[0]) for r in self._read("SELECT id FROM logs WHERE source_sha256 = ? ORDER BY id", (sha,))]
            if ids:
                out[Path(src.path)] = [self.log(i) for i in ids]
        return out

    def _ingest_sources(
        self,
        sources: list[Source],
        options: IngestOptions,
        fail: Callable[[IngestError], None],
        progress: Callable[[int, int], None] | None,
    ) -> list[LogInfo]:
        out: list[LogInfo] = []
        total = sum(s.size for s in sources)
        done = 0
        for source in sources:
            on_bytes = None if progress is None else (lambda n, base=done: progress(base + n, total))
            writers: list[NpyWriter] = []
            allocate = functools.partial(self._staged_file, writers)
            try:
                parsed, _ = read_source(source, options, on_bytes=on_bytes)
                aligned = []
                for p in parsed:
                    aligned.append(align(p, options, allocate=allocate))
                    writers[-1].close()
                out.extend(self._store(aligned, source.files))
            except IngestError as err:
                fail(err)
            except OSError as exc:
                raise SessionError(f"{self.path}: cannot write to the session: {exc.strerror or exc}") from None
            finally:
                for w in writers:  # closed or not, placed or not: a staged file left here is garbage
                    with contextlib.suppress(OSError):
                        w.abort()
            done += source.size
            if progress is not None:
                progress(done, total)
        return out

    def _staged_file(self, writers: list[NpyWriter], shape: tuple[int, int]) -> NpyWriter:
        """A staged file in the logs folder that aligned rows go straight to: a long log never sits in memory."""
        try:
            writers.append(NpyWriter(self.path / LOGS_DIR / f".tmp-{uuid.uuid4().hex}.npy", shape, np.float32))
        except OSError as exc:
            raise SessionError(f"{self.path}: cannot write to the session: {exc.strerror or exc}") from None
        return writers[-1]

    def _store(self, aligned: list[AlignedLog], files: Sequence[Path]) -> list[LogInfo]:
        try:
            sha = _sha256(files)
        except OSError as exc:
            raise IngestError(files[0], f"cannot read: {exc.strerror or exc}") from None
        try:
            return self._write_logs(aligned, sha)
        except OSError as exc:
            # Not the file's fault (disk full, read-only folder): stop, the session is as it was.
            raise SessionError(f"{self.path}: cannot write to the session: {exc.strerror or exc}") from None

    def _write_logs(self, aligned: list[AlignedLog], sha: str) -> list[LogInfo]:
        logs_dir = self.path / LOGS_DIR
        # The same recording again keeps the copy we have: no array is written for it (found by the name it was
        # read as: a log renamed to keep names unique keeps that name in its info)
        stored = self._read("SELECT name, info, id FROM logs WHERE source_sha256 = ? ORDER BY id", (sha,))
        ids = {json.loads(info).get("read_as", name): int(i) for name, info, i in stored}
        read_as = [log.parsed.name for log in aligned]
        if stored and not set(read_as) & set(ids) and len(stored) == len(read_as):
            # the same recording under another file name (a copy, a link): the logs we have, read in the same order
            ids = {name: int(row[2]) for name, row in zip(read_as, stored, strict=True)}
        staged: list[tuple[AlignedLog, Path]] = []
        cameras: dict[str, list[tuple[Path, Path, dict]]] = {}
        poses: dict[str, list[tuple[Path, dict]]] = {}
        placed: list[Path] = []
        try:
            for log in aligned:
                if log.parsed.name in ids:
                    continue
                assert isinstance(log.data, NpyWriter), "ingest aligns into staged files"
                staged.append((log, log.data.path))  # written and synced while aligning
                cameras[log.parsed.name] = stage_cameras(logs_dir, log.parsed.cameras, t0=log.t0)
                poses[log.parsed.name] = stage_poses(logs_dir, log.parsed.poses, t0=log.t0)
            with self._write() as conn:
                for log, tmp in staged:
                    same = [  # another process may have ingested it meanwhile
                        int(i)
                        for name, info, i in conn.execute(
                            "SELECT name, info, id FROM logs WHERE source_sha256 = ?", (sha,)
                        ).fetchall()
                        if json.loads(info).get("read_as", name) == log.parsed.name
                    ]
                    if same:
                        ids[log.parsed.name] = same[0]
                        continue
                    log_id = self._insert_log(conn, log, sha, tmp.name, name=unique_log_name(conn, log.parsed))
                    final = logs_dir / f"{log_id:06d}.npy"
                    conn.execute("UPDATE logs SET file = ? WHERE id = ?", (f"{LOGS_DIR}/{final.name}", log_id))
                    os.replace(tmp, final)
                    placed.append(final)
                    extra = {}
                    if cameras[log.parsed.name]:
                        extra["cameras"], files = place_cameras(logs_dir, log_id, cameras[log.parsed.name])
                        placed.extend(files)
                    if poses[log.parsed.name]:
                        extra["poses"], files = place_poses(logs_dir, log_id, poses[log.parsed.name])
                        placed.extend(files)
                    if extra:
                        row = conn.execute("SELECT info FROM logs WHERE id = ?", (log_id,)).fetchone()
                        info = {**json.loads(row[0]), **extra}
                        conn.execute("UPDATE logs SET info = ? WHERE id = ?", (json.dumps(info), log_id))
                    ids[log.parsed.name] = log_id
                fsync_dir(logs_dir)
        except BaseException:
            for p in placed:
                with contextlib.suppress(OSError):
                    p.unlink()
            raise
        finally:
            for _, tmp in staged:
                with contextlib.suppress(OSError):
                    tmp.unlink()
            leftover = [p for cams in cameras.values() for c in cams for p in c[:2]]
            for p in leftover + [tmp for tracks in poses.values() for tmp, _ in tracks]:
                with contextlib.suppress(OSError):
                    p.unlink()
        return [self.log(ids[log.parsed.name]) for log in aligned]

    @staticmethod
    def _insert_log(
        conn: sqlite3.Connection, log: AlignedLog, sha: str, tmp_name: str, *, name: tuple[str, str | None]
    ) -> int:
        p = log.parsed
        info = {"files": list(p.files), "stream_rates_hz": log.stream_rates, "notes": list(p.notes)}
        if name[1] is not None:  # renamed: a name names one run (labels by name land on it, exports tell them apart)
            info["read_as"] = p.name
            info["notes"].insert(0, name[1])
        cur = conn.execute(
            "INSERT INTO logs (name, source_path, source_sha256, format, file, n_samples, rate_hz, t0, "
            "reference_terrain, info, ingested_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (
                name[0],
                p.source_path,
                sha,
                p.format,
                tmp_name,
                log.data.shape[0],
                log.rate_hz,
                log.t0,
                p.reference_terrain,
                json.dumps(info),
                _labels.now(),
            ),
        )
        log_id = int(cur.lastrowid)
        conn.executemany(
            "INSERT INTO channels (log_id, idx, name, unit, source) VALUES (?, ?, ?, ?, ?)",
            [(log_id, i, c.name, c.unit, c.source) for i, c in enumerate(log.channels)],
        )
        conn.executemany(
            "INSERT INTO gaps (log_id, start, stop, stream, reason) VALUES (?, ?, ?, ?, ?)",
            [(log_id, g.start, g.stop, g.stream, g.reason) for g in log.gaps],
        )
        reference = list(log.reference)
        if not reference and p.reference_terrain:
            reference = [(0, log.data.shape[0], p.reference_terrain)]
        conn.executemany(
            "INSERT INTO reference (log_id, start, stop, terrain) VALUES (?, ?, ?, ?)",
            [(log_id, a, b, t) for a, b, t in reference],
        )
        return log_id


def unique_log_name(conn: sqlite3.Connection, parsed: ParsedLog) -> tuple[str, str | None]:
    """The name a new log is stored under, and the note that says why when it is not the one it was read as: a log
    of another recording already has that name, so the new one is ``NAME-2`` (``-3``, ...): every lookup by name
    (label files, suggestions, exports) must land on one run."""
    taken = {str(r[0]) for r in conn.execute("SELECT name FROM logs").fetchall()}
    if parsed.name not in taken:
        return parsed.name, None
    other = conn.execute("SELECT source_path FROM logs WHERE name = ?", (parsed.name,)).fetchone()[0]
    k = 2
    while f"{parsed.name}-{k}" in taken:
        k += 1
    name = f"{parsed.name}-{k}"
    return name, f"named {name}: the session has another log named {parsed.name} (from {other})"
