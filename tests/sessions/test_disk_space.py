"""Disk trouble named as what it is (issue 99, item 7): read-only, no space, and where; never "not a usable session
database" for a folder that is only read-only or full."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from sessions import SessionError, check_room, disk_space


def test_a_read_only_folder_and_a_full_disk_are_said_as_such(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    db = tmp_path / "session.sqlite"
    db.write_bytes(b"")
    error = sqlite3.OperationalError("attempt to write a readonly database")
    monkeypatch.setattr(disk_space.os, "access", lambda p, mode: False)  # as on a read-only mount (root included)
    assert disk_space.unusable_words(tmp_path, db, error).startswith(f"{tmp_path}: the session folder is read-only")
    monkeypatch.setattr(disk_space.os, "access", lambda p, mode: True)
    monkeypatch.setattr(disk_space, "free_bytes", lambda p: 300_000)
    full = sqlite3.OperationalError("database or disk is full")
    said = disk_space.unusable_words(tmp_path, db, full)
    assert (
        said
        == f"{tmp_path}: no space left on the disk holding the session (0.3 MB free); free some space and open it again"
    )
    monkeypatch.setattr(disk_space, "free_bytes", lambda p: 10 << 30)
    damaged = sqlite3.DatabaseError("file is not a database")
    assert (
        disk_space.unusable_words(tmp_path, db, damaged)
        == f"{db}: not a usable session database (file is not a database)"
    )


def test_a_write_the_disk_has_no_room_for_is_refused_before_the_work(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(disk_space, "free_bytes", lambda p: 1 << 20)
    with pytest.raises(SessionError, match=r"no space left for the export: 1.0 MB free on its disk, about 8.0 MB"):
        check_room(tmp_path, 8 << 20, what="the export")
    check_room(tmp_path, 1 << 19, what="the export")  # room enough: nothing said
