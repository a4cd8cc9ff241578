"""A consistent copy of a session folder, for work that must leave the session as it is."""

from __future__ import annotations

import os
import shutil
import sqlite3
from pathlib import Path

from .errors import SessionError
from .log_ingest import LOGS_DIR

DB_NAME = "session.sqlite"


def _link_or_copy(src: str, dst: str) -> None:
    """A hard link where the file system allows one (same device), else a copy."""
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def copy_session(path: Path, conn: sqlite3.Connection, dest: Path) -> Path:
    """Copy the session at ``path`` (its open connection ``conn``, held by the caller's lock) to the new ``dest``.

    The store is copied by SQLite's online backup, consistent while others write; then every file: the log arrays
    and camera frames hard-linked where the file system allows (they are written once and never changed), models
    and caches copied. A file written after the store's copy is an orphan there, never a reference to a missing
    file.

    Raises:
        SessionError: ``dest`` exists, or the copy failed (nothing is left at ``dest``).
    """
    if os.path.lexists(dest):
        raise SessionError(f"{dest}: exists already; a session is copied to a new folder")
    tmp = dest.with_name(f".{dest.name}.copying")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        tmp.mkdir(parents=True)
        target = sqlite3.connect(tmp / DB_NAME)
        try:
            conn.backup(target)
        finally:
            target.close()
        for item in path.iterdir():
            if item.name.startswith(DB_NAME) or item.is_symlink():
                continue
            if item.is_dir():
                linked = item.name == LOGS_DIR
                shutil.copytree(item, tmp / item.name, copy_function=_link_or_copy if linked else shutil.copy2)
            elif item.is_file():
                shutil.copy2(item, tmp / item.name)
        tmp.rename(dest)
    except (OSError, sqlite3.Error) as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        raise SessionError(f"{path}: cannot copy the session to {dest} ({exc})") from None
    return dest
