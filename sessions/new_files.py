"""Files the workbench writes where a person asks: always new, never through a link, never over a file.

Every command that writes a file or folder a person names (``suggest``, ``labels export``, ``classify``,
``evaluate --out``, ``export``) checks the target here once, before any work, and writes a file here: under a
temporary name beside the target, then linked to the target's name only if nothing took that name meanwhile
(``os.link`` fails on any existing entry, a dangling symbolic link included, where a rename would replace it). A
file made at the target while the work ran is left as it is and the command says so.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import secrets
from collections.abc import Iterator
from pathlib import Path

from .errors import WorkbenchError

# link(2) is missing on some file systems (FAT, some network mounts): there the target is claimed with O_EXCL
NO_HARD_LINKS = {errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS, errno.EMLINK}


def check_new_target(path: Path, *, what: str = "file") -> None:
    """Refuse ``path`` as the target of a new file or folder, before any work is done.

    Args:
        path: Where the person asked for the output.
        what: ``"file"`` or ``"folder"``, for the message.

    Raises:
        WorkbenchError: ``path`` exists (a file, a folder, a symbolic link of any kind, a dangling one included), or
            its folder is missing, is not a folder, or cannot be written in.
    """
    path = Path(path)
    if os.path.lexists(path):
        if path.is_symlink():
            kind = "a symbolic link" + ("" if path.exists() else " to nothing")
        elif path.is_dir():
            kind = "a folder"
        else:
            kind = "a file"
        raise WorkbenchError(f"{path}: exists already ({kind}); the workbench writes a new {what}, choose a new name")
    parent = path.parent
    if not os.path.lexists(parent):
        raise WorkbenchError(f"{path}: the folder {parent} does not exist; create it first")
    if not parent.is_dir():
        raise WorkbenchError(f"{path}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise WorkbenchError(f"{path}: cannot write in the folder {parent} (permission denied)")


def check_new_targets(paths: list[Path], *, what: str = "file") -> None:
    """:func:`check_new_target` for each of ``paths``, the first refused one named."""
    for path in paths:
        check_new_target(path, what=what)


def staging_name(path: Path) -> Path:
    """A fresh hidden name beside ``path`` that keeps its suffix (writers choose a format by it)."""
    return path.with_name(f".{secrets.token_hex(4)}.{path.name[-200:]}")


@contextlib.contextmanager
def new_file(path: Path) -> Iterator[Path]:
    """Write a new file at ``path``: yields a temporary path beside it to write, which takes ``path``'s name when the
    block ends without error, only if ``path`` still does not exist; the temporary file is removed in every case.

    Raises:
        WorkbenchError: ``path`` is refused by :func:`check_new_target` (before the block runs), or something took
            its name while the block ran (nothing is replaced).
    """
    path = Path(path)
    check_new_target(path)
    tmp = staging_name(path)
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # the umask applies, as to any new file
    except OSError as exc:
        raise WorkbenchError(f"{path}: cannot write in {path.parent} ({exc.strerror or exc})") from None
    try:
        yield tmp
        publish(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def publish(tmp: Path, path: Path) -> None:
    """Give the written file ``tmp`` the name ``path`` only if nothing has that name; ``tmp`` stays for the caller to
    remove.

    Raises:
        WorkbenchError: ``path`` exists now.
    """
    taken = f"{path}: was created while the output was written; it is left as it is and nothing was written"
    try:
        os.link(tmp, path)
        return
    except FileExistsError:
        raise WorkbenchError(taken) from None
    except OSError as exc:
        if exc.errno not in NO_HARD_LINKS:
            raise WorkbenchError(f"{path}: cannot write it ({exc.strerror or exc})") from None
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o666)
    except FileExistsError:
        raise WorkbenchError(taken) from None
    os.close(fd)
    os.replace(tmp, path)  # over the empty file this call created: nobody else's


AT_FDCWD = -100
RENAME_NOREPLACE = 1


def rename_new(tmp: Path, path: Path) -> None:
    """Rename the folder (or file) ``tmp`` to ``path`` only if nothing has that name: ``renameat2`` with
    ``RENAME_NOREPLACE`` where the C library has it (a plain rename would replace an empty folder or a link made
    meanwhile), else a check just before the rename.

    Raises:
        WorkbenchError: ``path`` exists now.
    """
    taken = f"{path}: was created while the output was written; it is left as it is and nothing was written"
    rename2 = _renameat2()
    if rename2 is not None:
        if rename2(AT_FDCWD, os.fsencode(tmp), AT_FDCWD, os.fsencode(path), RENAME_NOREPLACE) == 0:
            return
        err = ctypes.get_errno()
        if err == errno.EEXIST:
            raise WorkbenchError(taken)
        if err not in (errno.ENOSYS, errno.EINVAL):  # EINVAL: the file system cannot do it without replacing
            raise WorkbenchError(f"{path}: cannot write it ({os.strerror(err)})")
    if os.path.lexists(path):
        raise WorkbenchError(taken)
    os.rename(tmp, path)


def _renameat2():
    """The C library's ``renameat2``, or ``None`` (not Linux, or a glibc older than 2.28)."""
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    return fn
