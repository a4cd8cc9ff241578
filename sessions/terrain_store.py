"""The terrains part of :class:`sessions.Session`: the classes a person labels with, in display order."""

from __future__ import annotations

import re
import sqlite3
import threading
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager

from . import labels as _labels
from .errors import LabelError
from .logs import Terrain
from .terrain_rows import delete_terrain, insert_terrain, names_since, rename_terrain_row

# Terrain colours reach the page as CSS: only this form is stored (a colour is data a session file could carry).
TERRAIN_COLOR = re.compile(r"#[0-9a-fA-F]{6}")


class TerrainStore:
    """The terrains part of :class:`sessions.Session` (a mixin over its connection and lock)."""

    _conn: sqlite3.Connection
    _lock: threading.RLock
    _write: Callable[[], AbstractContextManager[sqlite3.Connection]]
    _read: Callable[..., list[tuple]]

    def terrains(self) -> list[Terrain]:
        """Terrain classes in display order."""
        return [Terrain(*r) for r in self._read("SELECT id, name, color, position FROM terrains ORDER BY position")]

    def add_terrain(self, name: str, *, color: str | None = None) -> Terrain:
        """Add a terrain class at the end of the list (colour: a usual one for a usual name, else the next of a
        palette).

        Raises:
            LabelError: The name is empty or taken, or the colour is not ``#rrggbb``.
        """
        name = name.strip()
        if color is not None and not TERRAIN_COLOR.fullmatch(color):
            raise LabelError(f"terrain colour {color!r} is not #rrggbb (six hex digits), e.g. #607d8b")
        with self._write() as conn:
            insert_terrain(conn, name, color)
        return next(t for t in self.terrains() if t.name == name)

    def rename_terrain(self, old: str, new: str) -> None:
        """Rename a terrain class; its segments, checks and reference rows follow, and the old name is kept for the
        models and files that used it (:meth:`terrain_names_since`)."""
        with self._write() as conn:
            rename_terrain_row(conn, old, new.strip(), at=_labels.now())

    def terrain_names_since(self, at: str) -> dict[str, str]:
        """Every name a terrain has had since ``at`` (an ISO time stamp, such as a model version's ``created_at``),
        to its name now: a model's classes and a suggestion file's guesses are named as they were then."""
        with self._lock:
            return names_since(self._conn, at)

    def remove_terrains(self, names: Sequence[str]) -> None:
        """Remove terrain classes no segment uses, in one transaction: all of them or, when any is unknown or used,
        none.

        Raises:
            LabelError: Unknown, or still used by segments.
        """
        with self._write() as conn:
            for name in names:
                delete_terrain(conn, name)

    def remove_terrain(self, name: str) -> None:
        """Remove a terrain class no segment uses.

        Raises:
            LabelError: Unknown, or still used by segments.
        """
        with self._write() as conn:
            delete_terrain(conn, name)
