"""What a panel may ask of the page it sits in: the one interface between ``ClientView`` and its panels.

Panels (label, suggestions, training, data, robot) type against :class:`PanelHost`, never against the view's
private parts, so the view can change its layout and drawing without breaking them, and a panel can be tested with a
small stand-in host.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Protocol

from sessions import LogInfo

if TYPE_CHECKING:
    import viser

    from .jobs import TrainJob
    from .state import SharedState


class RangeLabeller(Protocol):
    """What the Suggest tab asks of the Label tab: select a suggestion's range, and save it."""

    def select(self, start: int, stop: int, terrain: str | None = None) -> None:
        """Select samples ``[start, stop)`` of the log on screen, and optionally a terrain."""
        ...

    def save(self, *, terrain: str | None = None, source: str = "manual") -> None:
        """Label the selected range (one SQLite transaction); ``source`` records where the label came from."""
        ...


class PanelHost(Protocol):
    """One browser's page, as its panels see it.

    Attributes:
        client: The browser's viser handle (panels add their widgets through ``client.gui``).
        state: The state shared by every browser: session, scores, suggestions.
        job: The server's one training job.
        author: Who this browser's label actions are recorded as.
        log: The log on screen (``None`` before any log was ingested).
        selection: The range ``[start, stop)`` in samples of ``log``, or ``None``.
        cursor_s: The cursor, in seconds of ``log``.
        label_panel: The Label tab: a suggestion is labelled through it.
    """

    client: viser.ClientHandle
    state: SharedState
    job: TrainJob
    author: str
    log: LogInfo | None
    selection: tuple[int, int] | None
    cursor_s: float
    label_panel: RangeLabeller

    def guard(self, fn: Callable[[], None]) -> None:
        """Run a widget callback under the page's lock unless the server itself moved the widget; a user's error
        becomes a notification, never a traceback."""
        ...

    def notify(self, title: str, body: str, *, color: str = "green", seconds: float = 4.0) -> None:
        """A notification in the page."""
        ...

    def quiet(self) -> AbstractContextManager[None]:
        """Widgets changed inside this block are moved by the server: their callbacks do not echo."""
        ...

    def set_widget(self, handle: object, value: object) -> None:
        """Move a widget from the server without triggering its callback."""
        ...

    def show(self, log: LogInfo, *, start_s: float | None = None, stop_s: float | None = None) -> None:
        """Show a log; with a range, centre it in the window and put the cursor on it."""
        ...

    def move_cursor(self, seconds: float) -> None:
        """Move the cursor (the window follows when it leaves it)."""
        ...

    def redraw(self) -> None:
        """Draw the window again (after the selection or the state changed)."""
        ...
