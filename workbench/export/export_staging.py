"""Where an export is written before it is whole: ``.NAME.partial`` beside the folder it becomes.

An export is renamed into place only when every file is written, so a failed one leaves no half folder. A process
killed mid-export (``kill -9``, a power cut) cannot clean up, and its ``.NAME.partial`` stayed until the next export
to that same name. Each staging folder now holds an advisory lock (``flock``) for as long as its export lives: the
next export into the same parent folder, whatever its name, removes every staging folder whose lock nobody holds,
and leaves a live export's alone. A staging folder without a lock file (the instant between ``mkdir`` and the lock,
or one written before the lock existed) is removed only once it is a minute old and looks like an export (empty, or
holding ``bundle/``): a folder of someone else's that happens to be named ``.X.partial`` is never touched.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import shutil
import time
from collections.abc import Iterator
from pathlib import Path

from sessions import WorkbenchError

LOCK_FILE = ".export.lock"
UNLOCKED_GRACE_S = 60.0


def staging_folder(out: Path) -> Path:
    """The folder an export to ``out`` is written in first."""
    return out.with_name(f".{out.name}.partial")


def _held(lock: Path) -> bool | None:
    """Whether a live process holds ``lock``; ``None`` when there is no lock file."""
    try:
        fd = os.open(lock, os.O_RDWR)
    except FileNotFoundError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing drops the lock taken just now
    return False


def sweep_dead_exports(folder: Path) -> list[Path]:
    """Remove the staging folders in ``folder`` that killed exports left. Returns those removed."""
    removed = []
    with contextlib.suppress(OSError):
        candidates = [p for p in folder.glob(".*.partial") if p.is_dir() and not p.is_symlink()]
        for path in candidates:
            held = _held(path / LOCK_FILE)
            if held:
                continue
            if held is None:
                young = time.time() - path.stat().st_mtime < UNLOCKED_GRACE_S
                if young or not (not any(path.iterdir()) or (path / "bundle").is_dir()):
                    continue
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def check_target(out: Path) -> None:
    """Refuse ``out`` before any work when an export could not be renamed to it.

    Raises:
        WorkbenchError: ``out`` exists (a dangling symbolic link included: it took 11 s of work to fail on one), or
            its parent is not a folder.
    """
    if os.path.lexists(out):
        kind = "a symbolic link" if out.is_symlink() else "it"
        raise WorkbenchError(f"{out}: exists already ({kind}); choose a new folder")
    parent = out.parent
    if os.path.lexists(parent) and not parent.is_dir():
        raise WorkbenchError(f"{out}: {parent} is not a folder")


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Path]:
    """A fresh staging folder for an export to ``out``, renamed to ``out`` when the block ends without error and
    removed when it raises.

    Raises:
        WorkbenchError: ``out`` exists, or another live export is writing to it.
    """
    check_target(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sweep_dead_exports(out.parent)
    tmp = staging_folder(out)
    try:
        tmp.mkdir()
    except FileExistsError:
        raise WorkbenchError(f"{out}: another export to it is running ({tmp} is held)") from None
    fd = os.open(tmp / LOCK_FILE, os.O_CREAT | os.O_RDWR, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield tmp
        os.unlink(tmp / LOCK_FILE)  # the lock itself stays held through the rename: the descriptor is open
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        os.close(fd)
