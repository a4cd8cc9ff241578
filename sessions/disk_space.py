"""Disk trouble named as what it is: a read-only session folder, a full disk, and the room a write needs checked
before the work that ends in it (a fit of minutes that fails at its save loses the minutes, never a label)."""

from __future__ import annotations

import os
import shutil
import sqlite3
from pathlib import Path

from .errors import SessionError

MB = 1 << 20


def free_bytes(path: Path) -> int | None:
    """Bytes free on the disk holding ``path`` (``None``: it cannot be asked)."""
    try:
        return shutil.disk_usage(path).free
    except OSError:
        return None


def check_room(path: Path, need: int, *, what: str) -> None:
    """Refuse, before the work, a write of about ``need`` bytes into ``path`` that the disk has no room for.

    Raises:
        SessionError: Less than ``need`` bytes are free there, said with both figures and what was asked.
    """
    free = free_bytes(path)
    if free is not None and free < need:
        raise SessionError(
            f"{path}: no space left for {what}: {free / MB:.1f} MB free on its disk, about {need / MB:.1f} MB "
            "needed; free some space and run it again (nothing was changed)"
        )


def folder_bytes(path: Path) -> int:
    """The bytes of the files under ``path`` (0 where it is missing)."""
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def unusable_words(path: Path, db: Path, exc: sqlite3.DatabaseError) -> str:
    """Why the session ``path``'s database ``db`` cannot be opened, in the words of its cause: a read-only folder or
    file, a full disk, or a damaged file."""
    if not os.access(path, os.W_OK) or not os.access(db, os.W_OK):
        return (
            f"{path}: the session folder is read-only here; the workbench keeps its labels there and must write "
            "to it (copy it somewhere writable, or open it as a user who may write)"
        )
    free = free_bytes(path)
    if "full" in str(exc).lower() or (free is not None and free < MB):
        shown = "" if free is None else f" ({free / MB:.1f} MB free)"
        return f"{path}: no space left on the disk holding the session{shown}; free some space and open it again"
    return f"{db}: not a usable session database ({exc})"
