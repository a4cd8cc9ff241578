"""The one error family: every error a user can cause, in any package, and how it reaches a person.

``sessions``, ``training`` and ``labeling`` never import each other, so no class can be the base of all three; each
package has one root (``sessions.WorkbenchError``, ``training.TrainingError``; ``labeling`` takes arrays and raises
no error a user causes), and this module names them together. The CLI and the UI catch :data:`USER_ERRORS` and show
:func:`one_line`; anything else is an internal error. ``tests/test_layout.py`` checks that every ``*Error`` class of
the packages derives from one of these roots.
"""

from __future__ import annotations

from sessions import WorkbenchError
from training import TrainingError

USER_ERRORS: tuple[type[Exception], ...] = (WorkbenchError, TrainingError)


def one_line(exc: BaseException) -> str:
    """The error's message on one line (a library's message may carry newlines)."""
    return " ".join(str(exc).split())
