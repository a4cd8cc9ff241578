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

from sessions import WorkbenchError, check_new_target, rename_new

from ..scratch_folders import held

LOCK_FILE = ".export.lock"
UNLOCKED_GRACE_S = 60.0


def staging_folder(out: Path) -> Path:
    """The folder an export to ``out`` is written in first."""
    return out.with_name(f".{out.name}.partial")


def sweep_dead_exports(folder: Path) -> list[Path]:
    """Remove the staging folders in ``folder`` that killed exports left. Returns those removed."""
    removed = []
    with contextlib.suppress(OSError):
        candidates = [p for p in folder.glob(".*.partial") if p.is_dir() and not p.is_symlink()]
        for path in candidates:
            held_now = held(path / LOCK_FILE)
            if held_now:
                continue
            if held_now is None:
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
            its folder is missing or is not a folder (``sessions.check_new_target``).
    """
    check_new_target(out, what="folder")


@contextlib.contextmanager
def staged(out: Path) -> Iterator[Path]:
    """A fresh staging folder for an export to ``out``, renamed to ``out`` when the block ends without error and
    removed when it raises.

    Raises:
        WorkbenchError: ``out`` exists, or another live export is writing to it.
    """
    check_target(out)
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
        rename_new(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        os.close(fd)
