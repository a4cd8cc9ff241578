"""The person's checks: what the active model said where a label was made, before it trained on it (test then
train).

A label placed where the model already had an opinion is a test of that model on time it never trained on: the
person's own held-out evidence, and the only one that covers the runs nobody labelled before. Each row keeps the
piece labelled, the person's terrain, what the model said there (its terrain over most of the piece, and the share
of the piece it predicted as the person's), which classifier version said it, and how the piece was chosen: a
``suggestion`` (ranked where the model is unsure: a biased sample), a ``spot check`` (drawn uniformly over the
unlabelled time: a fair one), a ``main answer`` (the middle of the model's longest stretch in a run nobody checked:
biased the other way, to where the model is sure) or ``manual``. Checks are kept when labels are undone or changed:
the test happened.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from .errors import LabelError
from .labels import now

CHECK_KINDS = ("suggestion", "spot check", "manual", "stretch", "main answer")
# the kinds an estimate counts: a "stretch" check (the model's own stretch accepted) agrees with it by construction
COUNTED_KINDS = ("suggestion", "spot check", "manual", "main answer")


@dataclass(frozen=True)
class Check:
    """One check: the model's answer on a piece before the person's label there trained it.

    Attributes:
        id: Row id.
        log_id: The log.
        start: First sample of the piece.
        stop: One past its last sample.
        terrain: The person's terrain.
        predicted: The model's terrain over most of the piece.
        agreement: The share of the piece's steps the model predicted as the person's terrain.
        classifier: The classifier version that answered.
        kind: How the piece was chosen (``CHECK_KINDS``).
        author: Who labelled it.
        at: When (UTC, ISO 8601).
    """

    id: int
    log_id: int
    start: int
    stop: int
    terrain: str
    predicted: str
    agreement: float
    classifier: int
    kind: str
    author: str
    at: str

    @property
    def right(self) -> bool:
        """Whether the model named the person's terrain over most of the piece."""
        return self.predicted == self.terrain


_COLS = "id, log_id, start, stop, terrain, predicted, agreement, classifier, kind, author, at"


def insert_check(
    conn: sqlite3.Connection,
    log_id: int,
    start: int,
    stop: int,
    terrain: str,
    *,
    predicted: str,
    agreement: float,
    classifier: int,
    kind: str,
    author: str,
) -> tuple[Check, bool]:
    """Add a check inside the caller's transaction; a piece checks a classifier version once.

    A check of the same piece, version and kind as one kept already is that same test again (a file imported twice,
    a label undone and made again): the kept row takes the person's latest terrain, and nothing is counted twice.

    Returns:
        The check as kept, and whether it is new.

    Raises:
        LabelError: An unknown log or kind, or a bad range or agreement.
    """
    if kind not in CHECK_KINDS:
        raise LabelError(f"unknown check kind {kind!r}; one of {', '.join(CHECK_KINDS)}")
    if not (0 <= start < stop) or not 0.0 <= agreement <= 1.0:
        raise LabelError(f"a check of [{start}, {stop}) agreeing {agreement}: not a piece of a log")
    key = (log_id, start, stop, classifier, kind)
    same = "log_id = ? AND start = ? AND stop = ? AND classifier = ? AND kind = ?"
    kept = conn.execute(f"SELECT id FROM checks WHERE {same}", key).fetchone()
    if kept is not None:
        conn.execute(
            "UPDATE checks SET terrain = ?, agreement = ?, author = ?, at = ? WHERE id = ?",
            (terrain, agreement, author, now(), kept[0]),
        )
        return Check(*conn.execute(f"SELECT {_COLS} FROM checks WHERE id = ?", (kept[0],)).fetchone()), False
    try:
        cur = conn.execute(
            f"INSERT INTO checks ({_COLS.split(', ', 1)[1]}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (log_id, start, stop, terrain, predicted, agreement, classifier, kind, author, now()),
        )
    except sqlite3.IntegrityError:
        raise LabelError(f"a check of unknown log {log_id}") from None
    return Check(*conn.execute(f"SELECT {_COLS} FROM checks WHERE id = ?", (cur.lastrowid,)).fetchone()), True


class CheckStore:
    """The checks part of :class:`sessions.Session` (a mixin over its connection, lock and path)."""

    path: Path
    _conn: sqlite3.Connection
    _lock: threading.RLock
    _write: object  # Session's write-transaction context manager

    def add_check(
        self,
        log_id: int,
        start: int,
        stop: int,
        terrain: str,
        *,
        predicted: str,
        agreement: float,
        classifier: int,
        kind: str,
        author: str,
    ) -> Check:
        """Record what classifier ``classifier`` said on ``[start, stop)`` of a log the person labelled ``terrain``
        (once per piece, version and kind: :func:`insert_check`).

        Raises:
            LabelError: An unknown log or kind, or a bad range or agreement.
        """
        with self._write() as conn:  # type: ignore[attr-defined]
            check, _ = insert_check(
                conn,
                log_id,
                start,
                stop,
                terrain,
                predicted=predicted,
                agreement=agreement,
                classifier=classifier,
                kind=kind,
                author=author,
            )
            return check

    def record_issued(self, rows: Sequence[tuple[int, int, int, int, str, str | None]]) -> None:
        """Record the checks a ``suggest`` file offers, as the session drew them: ``(log id, start, stop,
        classifier, kind, guess)`` each (the guess: the classifier's terrain over the piece, as named now). A row of
        the file filled in is then a check of that kind and that guess (:func:`issued_check`); one drawn again
        keeps its first record."""
        with self._write() as conn:  # type: ignore[attr-defined]
            conn.executemany(
                "INSERT OR IGNORE INTO issued (log_id, start, stop, classifier, kind, guess, at) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(*r, now()) for r in rows],
            )

    def checks(self, log_id: int | None = None) -> list[Check]:
        """The checks, of one log or all, oldest first."""
        where, args = ("WHERE log_id = ?", (log_id,)) if log_id is not None else ("", ())
        with self._lock:
            rows = self._conn.execute(f"SELECT {_COLS} FROM checks {where} ORDER BY id", args).fetchall()
        return [Check(*r) for r in rows]


def issued_check(conn: sqlite3.Connection, log_id: int, start: int, stop: int, classifier: int) -> tuple | None:
    """What the session wrote for a piece of a ``suggest`` file: ``(kind, guess)``, or ``None`` when it wrote no
    such row (a file from elsewhere, or from before the session kept the record)."""
    row = conn.execute(
        "SELECT kind, guess FROM issued WHERE log_id = ? AND start = ? AND stop = ? AND classifier = ?",
        (log_id, start, stop, classifier),
    ).fetchone()
    return None if row is None else (str(row[0]), None if row[1] is None else str(row[1]))
