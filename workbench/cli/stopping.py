"""SIGTERM ends a command as Ctrl+C does: the stack unwinds, so what a command made for itself goes with it.

Python's default for SIGTERM kills the process where it stands: no ``finally`` runs, and ``evaluate loop`` left its
copy of the session (``workbench-loop-*``, 11 MB on the demo) in the temporary folder on every ``kill``. Raised as an
exception instead, it runs the same cleanup as Ctrl+C; ``workbench serve`` puts its own handlers in place
(``workbench.ui.app``: a stop flag the server's workers poll).
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Ctrl+C raises ``KeyboardInterrupt``."""


def _raise_terminated(signum: int, frame: Any) -> None:
    raise Terminated


@contextlib.contextmanager
def sigterm_unwinds() -> Iterator[None]:
    """While the block runs, SIGTERM raises :class:`Terminated` in the main thread (nothing changes elsewhere)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
