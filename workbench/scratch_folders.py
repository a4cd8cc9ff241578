"""Folders a command works in and removes when it ends, swept by the next command when a killed one left them.

A command killed with SIGKILL (or by a power cut) runs no cleanup. Each scratch folder holds an advisory lock
(``flock``) for as long as its command lives: the next command of the same kind removes every such folder whose lock
nobody holds, and leaves a live command's alone. ``evaluate loop``'s copies of a session and the export's staging
folders are swept so.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

LOCK_FILE = ".workbench.lock"


def held(lock: Path) -> bool | None:
    """Whether a live process holds the lock file ``lock``; ``None`` when there is no such file."""
    try:
        fd = os.open(lock, os.O_RDWR)
    except (FileNotFoundError, NotADirectoryError):
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing drops the lock taken just now
    return False


def sweep_scratch(prefix: str, *, folder: Path | None = None) -> list[Path]:
    """Remove the scratch folders named ``prefix*`` in ``folder`` (the temporary folder by default) whose command is
    gone: their lock is held by nobody. Returns those removed."""
    removed = []
    with contextlib.suppress(OSError):
        for path in Path(folder or tempfile.gettempdir()).glob(f"{prefix}*"):
            if path.is_dir() and not path.is_symlink() and held(path / LOCK_FILE) is False:
                shutil.rmtree(path, ignore_errors=True)
                removed.append(path)
    return removed


@contextlib.contextmanager
def scratch_folder(prefix: str, *, folder: Path | None = None) -> Iterator[Path]:
    """A new folder ``prefix*`` in ``folder`` (the temporary folder by default), locked while the block runs and
    removed when it ends, however it ends (SIGTERM and Ctrl+C included, ``workbench.cli.stopping``); the folders
    killed commands left are swept first."""
    sweep_scratch(prefix, folder=folder)
    path = Path(tempfile.mkdtemp(prefix=prefix, dir=folder))
    fd = os.open(path / LOCK_FILE, os.O_CREAT | os.O_RDWR, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield path
    finally:
        shutil.rmtree(path, ignore_errors=True)
        os.close(fd)
