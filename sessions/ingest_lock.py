"""Which staged files a live ingest still writes: every ingest holds a shared lock on ``logs/.ingest.lock`` while it
runs, and the sweep of leftovers takes it exclusively, without waiting.

The kernel drops a process's locks when it dies, SIGKILL included, so a sweep that gets the lock knows that no
ingest is writing and removes every staged file at once; before, it waited until a file was ten minutes old, and a
killed ingest's 40 GB staged array stayed in the session meanwhile.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # not POSIX: no locks, and the sweep goes by age alone
    fcntl = None  # type: ignore[assignment]

LOCK_NAME = ".ingest.lock"


@contextlib.contextmanager
def ingesting(logs_dir: Path) -> Iterator[None]:
    """Hold the shared lock while an ingest writes staged files (several ingests may hold it at once)."""
    try:
        f = open(logs_dir / LOCK_NAME, "a+b") if fcntl is not None else None  # noqa: SIM115 (closed below)
    except OSError:  # a read-only session: the ingest refuses in its own words when it writes
        f = None
    if f is None:
        yield
        return
    with f:
        fcntl.flock(f.fileno(), fcntl.LOCK_SH)  # waits only while a sweep runs (milliseconds)
        yield


@contextlib.contextmanager
def sweeping(logs_dir: Path) -> Iterator[bool]:
    """Take the lock exclusively if no ingest holds it; yields whether it did (then every staged file is garbage)."""
    if fcntl is None:
        yield False
        return
    try:
        f = open(logs_dir / LOCK_NAME, "a+b")  # noqa: SIM115 (closed below, which releases the lock)
    except OSError:  # a read-only session: nothing can be swept anyway
        yield False
        return
    with f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            yield False
            return
        yield True
