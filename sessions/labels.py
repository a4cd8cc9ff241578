"""Label segments with history and undo. Every function here runs inside the caller's write transaction.

Invariant kept by every operation: no two segments of one log overlap. A new or changed segment that overlaps or
touches segments of the *same* terrain merges with them; one that overlaps a *different* terrain is refused.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable
from datetime import UTC, datetime
from itertools import pairwise

from .errors import LabelError
from .logs import HistoryEntry, Segment

_SEGMENT_COLS = "id, log_id, start, stop, terrain_id, author, source, created_at, updated_at"


def now() -> str:
    """UTC time stamp, ISO 8601 with microseconds (sortable as text)."""
    return datetime.now(UTC).isoformat(timespec="microseconds")


def _row_dict(row: sqlite3.Row | tuple) -> dict[str, object]:
    keys = ("log_id", "start", "stop", "terrain_id", "author", "source", "created_at", "updated_at")
    return dict(zip(keys, tuple(row)[1:], strict=True))


def _get_row(conn: sqlite3.Connection, segment_id: int) -> tuple | None:
    return conn.execute(f"SELECT {_SEGMENT_COLS} FROM segments WHERE id = ?", (segment_id,)).fetchone()


def _terrain_id(conn: sqlite3.Connection, terrain: str) -> int:
    row = conn.execute("SELECT id FROM terrains WHERE name = ?", (terrain,)).fetchone()
    if row is None:
        names = [r[0] for r in conn.execute("SELECT name FROM terrains ORDER BY position")]
        raise LabelError(f"unknown terrain {terrain!r}; known terrains: {', '.join(names)}")
    return int(row[0])


def _terrain_name(conn: sqlite3.Connection, terrain_id: int) -> str:
    return str(conn.execute("SELECT name FROM terrains WHERE id = ?", (terrain_id,)).fetchone()[0])


def _check_range(conn: sqlite3.Connection, log_id: int, start: int, stop: int) -> None:
    row = conn.execute("SELECT n_samples, name FROM logs WHERE id = ?", (log_id,)).fetchone()
    if row is None:
        raise LabelError(f"unknown log id {log_id}")
    n_samples, name = row
    if not (0 <= start < stop <= n_samples):
        raise LabelError(
            f"segment [{start}, {stop}) is not inside log {name!r} (samples 0 to {n_samples}); "
            "start must be before stop"
        )


def _begin_op(conn: sqlite3.Connection, author: str, kind: str, *, undoes: int | None = None) -> int:
    cur = conn.execute(
        "INSERT INTO label_ops (at, author, kind, undoes) VALUES (?, ?, ?, ?)", (now(), author, kind, undoes)
    )
    return int(cur.lastrowid)


def _record(conn: sqlite3.Connection, op_id: int, segment_id: int, before: tuple | None, after: tuple | None):
    conn.execute(
        "INSERT INTO label_history (op_id, segment_id, before, after) VALUES (?, ?, ?, ?)",
        (
            op_id,
            segment_id,
            None if before is None else json.dumps(_row_dict(before)),
            None if after is None else json.dumps(_row_dict(after)),
        ),
    )


def _neighbours(conn: sqlite3.Connection, log_id: int, start: int, stop: int, exclude: int | None) -> list[tuple]:
    """Segments of ``log_id`` overlapping or touching ``[start, stop)`` (touching ones merge when of one terrain).

    Segments of a log never overlap, so ordered by start their stops rise too: walking back from the last segment
    starting at or before ``stop`` (the ``(log_id, start)`` index, read backwards), the first one ending before
    ``start`` ends the search. A filter on ``stop`` alone scanned every earlier segment, and importing n rows took
    O(n²) (10k one-sample rows 11.7 s, 20k 32.2 s).
    """
    found = []
    rows = conn.execute(
        f"SELECT {_SEGMENT_COLS} FROM segments WHERE log_id = ? AND start <= ? ORDER BY start DESC",
        (log_id, stop),
    )
    for row in rows:
        if row[3] < start:  # row[3] is stop
            break
        if row[0] != exclude:
            found.append(row)
    return found[::-1]


def _place(
    conn: sqlite3.Connection,
    op_id: int,
    *,
    log_id: int,
    start: int,
    stop: int,
    terrain_id: int,
    keep: int | None,
) -> tuple[int, int, list[tuple]]:
    """Resolve overlaps for a segment about to occupy ``[start, stop)``: refuse other terrains, absorb same ones.

    Returns the merged range and the absorbed rows (already deleted and recorded).
    """
    absorbed = []
    for row in _neighbours(conn, log_id, start, stop, keep):
        overlaps = row[2] < stop and row[3] > start
        if row[4] != terrain_id:
            if overlaps:
                raise LabelError(
                    f"overlaps segment #{row[0]} ({_terrain_name(conn, row[4])}, samples {row[2]}-{row[3]}) "
                    f"of another terrain; shrink or delete it first"
                )
            continue
        absorbed.append(row)
    for row in absorbed:
        start, stop = min(start, row[2]), max(stop, row[3])
        conn.execute("DELETE FROM segments WHERE id = ?", (row[0],))
        _record(conn, op_id, row[0], row, None)
    return start, stop, absorbed


def labelled_as(conn: sqlite3.Connection, log_id: int, start: int, stop: int, terrain: str) -> bool:
    """Whether ``[start, stop)`` of a log lies inside one segment of ``terrain`` (same-terrain segments that touch are
    merged, so one segment holds any stretch labelled so): adding it again would change nothing."""
    # segments of a log never overlap: only the last one starting at or before ``start`` can hold the span (one
    # step down the (log_id, start) index; a scan of every earlier segment made 100,000 rows quadratic)
    row = conn.execute(
        "SELECT stop, terrain_id FROM segments WHERE log_id = ? AND start <= ? ORDER BY start DESC LIMIT 1",
        (log_id, start),
    ).fetchone()
    if row is None or row[0] < stop:
        return False
    named = conn.execute("SELECT 1 FROM terrains WHERE id = ? AND name = ?", (row[1], terrain)).fetchone()
    return named is not None


def add_segment(
    conn: sqlite3.Connection,
    *,
    log_id: int,
    start: int,
    stop: int,
    terrain: str,
    author: str,
    source: str,
    kind: str = "add",
) -> Segment:
    """Insert a segment, merging same-terrain neighbours. Returns the segment as stored."""
    (segment,) = add_segments(
        conn, log_id=log_id, ranges=[(start, stop)], terrain=terrain, author=author, source=source, kind=kind
    )
    return segment


def add_segments(
    conn: sqlite3.Connection,
    *,
    log_id: int,
    ranges: Iterable[tuple[int, int]],
    terrain: str,
    author: str,
    source: str,
    kind: str = "accept",
) -> list[Segment]:
    """Insert several segments of one terrain as one action (one undo reverts them all); each merges as
    :func:`add_segment` does."""
    terrain_id = _terrain_id(conn, terrain)
    op_id = _begin_op(conn, author, kind)
    out = []
    for start, stop in ranges:
        _check_range(conn, log_id, start, stop)
        start, stop, _ = _place(conn, op_id, log_id=log_id, start=start, stop=stop, terrain_id=terrain_id, keep=None)
        at = now()
        cur = conn.execute(
            "INSERT INTO segments (log_id, start, stop, terrain_id, author, source, created_at, updated_at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
            (log_id, start, stop, terrain_id, author, source, at, at),
        )
        segment_id = int(cur.lastrowid)
        _record(conn, op_id, segment_id, None, _get_row(conn, segment_id))
        out.append(get_segment(conn, segment_id))
    return out


def change_segment(
    conn: sqlite3.Connection,
    segment_id: int,
    *,
    author: str,
    start: int | None = None,
    stop: int | None = None,
    terrain: str | None = None,
) -> Segment:
    """Move, resize or relabel a segment; it merges with same-terrain neighbours like a new one."""
    before = _get_row(conn, segment_id)
    if before is None:
        raise LabelError(f"no segment #{segment_id} (deleted meanwhile?)")
    log_id = int(before[1])
    new_start = int(before[2] if start is None else start)
    new_stop = int(before[3] if stop is None else stop)
    _check_range(conn, log_id, new_start, new_stop)
    terrain_id = int(before[4]) if terrain is None else _terrain_id(conn, terrain)
    op_id = _begin_op(conn, author, "change")
    new_start, new_stop, _ = _place(
        conn, op_id, log_id=log_id, start=new_start, stop=new_stop, terrain_id=terrain_id, keep=segment_id
    )
    conn.execute(
        "UPDATE segments SET start = ?, stop = ?, terrain_id = ?, updated_at = ? WHERE id = ?",
        (new_start, new_stop, terrain_id, now(), segment_id),
    )
    _record(conn, op_id, segment_id, before, _get_row(conn, segment_id))
    return get_segment(conn, segment_id)


def delete_segment(conn: sqlite3.Connection, segment_id: int, *, author: str) -> Segment:
    """Delete a segment; returns it as it was."""
    before = _get_row(conn, segment_id)
    if before is None:
        raise LabelError(f"no segment #{segment_id} (deleted meanwhile?)")
    gone = get_segment(conn, segment_id)
    op_id = _begin_op(conn, author, "delete")
    conn.execute("DELETE FROM segments WHERE id = ?", (segment_id,))
    _record(conn, op_id, segment_id, before, None)
    return gone


def _restore(conn: sqlite3.Connection, segment_id: int, state: dict[str, object] | None) -> None:
    conn.execute("DELETE FROM segments WHERE id = ?", (segment_id,))
    if state is not None:
        conn.execute(
            f"INSERT INTO segments ({_SEGMENT_COLS}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (segment_id, *state.values()),
        )


def _assert_no_overlap(conn: sqlite3.Connection, log_ids: Iterable[int]) -> None:
    for log_id in set(log_ids):
        rows = conn.execute(
            "SELECT id, start, stop FROM segments WHERE log_id = ? ORDER BY start", (log_id,)
        ).fetchall()
        for a, b in pairwise(rows):
            if b[1] < a[2]:
                raise LabelError(
                    f"cannot undo: segment #{a[0]} would overlap segment #{b[0]}, changed since; edit them instead"
                )


def undo(conn: sqlite3.Connection, *, author: str, only_author: bool = True) -> HistoryEntry:
    """Revert the latest label action not yet undone (by ``author`` unless ``only_author`` is False).

    Refused when a segment it touched was changed by a later action, so an undo never clobbers newer work.
    """
    query = "SELECT id FROM label_ops WHERE undone_by IS NULL AND kind != 'undo'"
    args: tuple = ()
    if only_author:
        query += " AND author = ?"
        args = (author,)
    row = conn.execute(query + " ORDER BY id DESC LIMIT 1", args).fetchone()
    if row is None:
        raise LabelError("nothing to undo")
    target = int(row[0])
    changes = conn.execute(
        "SELECT segment_id, before, after FROM label_history WHERE op_id = ? ORDER BY id DESC", (target,)
    ).fetchall()
    op_id = _begin_op(conn, author, "undo", undoes=target)
    touched_logs = []
    for segment_id, before_json, after_json in changes:
        current = _get_row(conn, segment_id)
        current_state = None if current is None else _row_dict(current)
        after = None if after_json is None else json.loads(after_json)
        if current_state != after:
            raise LabelError(f"cannot undo: segment #{segment_id} was changed by a later action")
        before = None if before_json is None else json.loads(before_json)
        _restore(conn, segment_id, before)
        _record(conn, op_id, segment_id, current, _get_row(conn, segment_id))
        touched_logs.extend(int(s["log_id"]) for s in (before, after) if s is not None)
    _assert_no_overlap(conn, touched_logs)
    conn.execute("UPDATE label_ops SET undone_by = ? WHERE id = ?", (op_id, target))
    return history(conn, op_id=target)[0]


def get_segment(conn: sqlite3.Connection, segment_id: int) -> Segment:
    """One segment by id."""
    found = list_segments(conn, segment_id=segment_id)
    if not found:
        raise LabelError(f"no segment #{segment_id}")
    return found[0]


def list_segments(
    conn: sqlite3.Connection, *, log_id: int | None = None, segment_id: int | None = None
) -> list[Segment]:
    """Segments ordered by log and start, optionally of one log or one id."""
    query = (
        "SELECT s.id, s.log_id, s.start, s.stop, t.name, s.author, s.source, s.created_at, s.updated_at "
        "FROM segments s JOIN terrains t ON t.id = s.terrain_id"
    )
    where, args = [], []
    if log_id is not None:
        where.append("s.log_id = ?")
        args.append(log_id)
    if segment_id is not None:
        where.append("s.id = ?")
        args.append(segment_id)
    if where:
        query += " WHERE " + " AND ".join(where)
    rows = conn.execute(query + " ORDER BY s.log_id, s.start", args).fetchall()
    return [Segment(*row) for row in rows]


def history(conn: sqlite3.Connection, *, op_id: int | None = None, limit: int | None = None) -> list[HistoryEntry]:
    """Label actions, newest first, each with the segment rows it changed."""
    query = "SELECT id, at, author, kind, undone_by FROM label_ops"
    args: list = []
    if op_id is not None:
        query += " WHERE id = ?"
        args.append(op_id)
    query += " ORDER BY id DESC"
    if limit is not None:
        query += " LIMIT ?"
        args.append(limit)
    entries = []
    for oid, at, author, kind, undone_by in conn.execute(query, args).fetchall():
        changes = tuple(
            (
                int(seg),
                None if b is None else json.loads(b),
                None if a is None else json.loads(a),
            )
            for seg, b, a in conn.execute(
                "SELECT segment_id, before, after FROM label_history WHERE op_id = ? ORDER BY id", (oid,)
            )
        )
        entries.append(HistoryEntry(oid, at, author, kind, undone_by, changes))
    return entries
