"""Errors the session layer raises. Each carries a message meant for a person, on one line."""

from __future__ import annotations

from pathlib import Path


class WorkbenchError(Exception):
    """Base class: an error a user can act on. The CLI prints ``str(err)`` and exits 2, no traceback."""


class SessionError(WorkbenchError):
    """The session folder is missing, damaged, or from a newer version of the workbench."""


class LabelError(WorkbenchError):
    """A label change was refused (overlap with another terrain, unknown log or terrain, bad range)."""


class IngestError(WorkbenchError):
    """A log file was refused. Names the file, the reason and where (row, byte offset or topic)."""

    def __init__(self, path: str | Path, reason: str, *, where: str | None = None) -> None:
        self.path = str(path)
        self.reason = reason
        self.where = where
        at = f" ({where})" if where else ""
        super().__init__(f"{self.path}: {reason}{at}")

    def __reduce__(self) -> tuple:
        """Pickled with its own arguments (``args`` holds the message alone): a file read in another process
        (``classify --jobs``) hands its refusal back whole."""
        return _ingest_error, (self.path, self.reason, self.where)


def _ingest_error(path: str, reason: str, where: str | None) -> IngestError:
    return IngestError(path, reason, where=where)
