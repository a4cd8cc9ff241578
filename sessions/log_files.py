"""A log's array file, checked before it is read: the catalog names it, but the file is data anyone could replace.

A session folder may come from someone else (a colleague's share, a download). ``session.sqlite`` naming
``logs/000001.npy`` is no promise that the file is still the float32 array ingest wrote: it may be a link to a
system file, an array of Python objects (which NumPy would unpickle, running code), or of another shape. Each is
refused with one line before anything reads it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np

from .errors import SessionError
from .logs import LogInfo

FLOAT32 = np.dtype("<f4")


def checked_in_logs(session: Path, rel: str, *, name: str, what: str) -> tuple[Path, os.stat_result]:
    """A file the catalog names (``rel``), refused unless it is a regular file inside ``session/logs``.

    Raises:
        SessionError: ``{name}: {what} ...`` when it leaves the logs folder, is missing, a link or no regular file.
    """
    p = Path(rel)
    if p.is_absolute() or ".." in p.parts or p.parts[:1] != ("logs",):
        raise SessionError(f"{name}: the catalog points outside the session's logs folder; the session was changed")
    path = session / p
    try:
        info = path.lstat()
    except OSError as exc:
        raise SessionError(f"{name}: cannot read {what} ({exc.strerror or exc}); re-ingest the log") from None
    if stat.S_ISLNK(info.st_mode) or not stat.S_ISREG(info.st_mode):
        raise SessionError(f"{name}: {what} is a link or no regular file; the session was changed")
    return path, info


def checked_log_file(session: Path, log: LogInfo) -> tuple[Path, int]:
    """The path of ``log``'s array inside ``session`` and the byte offset of its data.

    Raises:
        SessionError: The catalog's path leaves ``session/logs``, the file is a link or no regular file, or it is
            not a C-ordered float32 ``.npy`` array of the log's ``(samples, channels)``, whole.
    """
    name = f"{session}: log {log.name!r} ({log.file})"
    path, info = checked_in_logs(session, log.file, name=name, what="the log's array")
    try:
        with open(path, "rb") as f:
            version = np.lib.format.read_magic(f)
            read_header = (
                np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            )
            shape, fortran, dtype = read_header(f)
            offset = f.tell()
    except (OSError, ValueError) as exc:
        raise SessionError(f"{name}: the log's array is no .npy file ({exc}); the session was changed") from None
    want = (log.n_samples, log.n_channels)
    if dtype != FLOAT32 or fortran or tuple(shape) != want:
        raise SessionError(
            f"{name}: the log's array is {dtype} {tuple(shape)}{' (Fortran order)' if fortran else ''}, "
            f"not float32 {want}; the session was changed"
        )
    if info.st_size < offset + log.n_samples * log.n_channels * FLOAT32.itemsize:
        raise SessionError(f"{name}: the log's array is cut short ({info.st_size} bytes); the session was changed")
    return path, offset
