"""The events the shared state sends its views ("labels", "scores", "suggestions", "job", "models", "logs"), delivered
by one thread of their own."""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable

from ..user_errors import USER_ERRORS, one_line

Event = str  # "labels" | "scores" | "suggestions" | "job" | "models" | "logs"
Listener = Callable[[Event], None]


class Events:
    """Listeners, and a thread that delivers what :meth:`notify` queued until :meth:`stop`."""

    def __init__(self, *, on_error: Callable[[str], None]) -> None:
        self._on_error = on_error
        self._lock = threading.Lock()
        self._listeners: list[Listener] = []
        self._pending: dict[Event, None] = {}  # events not yet delivered, in order
        self._pending_cv = threading.Condition()
        self._delivering = False
        self._stopped = False
        self._thread = threading.Thread(target=self._deliver, name="workbench-events", daemon=True)
        self._thread.start()

    def subscribe(self, fn: Listener) -> Callable[[], None]:
        """Call ``fn(event)`` for every event from now on; returns what unsubscribes it."""
        with self._lock:
            self._listeners.append(fn)

        def unsubscribe() -> None:
            with self._lock:
                if fn in self._listeners:
                    self._listeners.remove(fn)

        return unsubscribe

    def notify(self, event: Event) -> None:
        """Tell every listener that ``event`` happened; returns at once.

        One thread delivers events, never the caller: a view's callback holds that view's lock while it changes the
        state, and delivering to the other views from there took their locks in turn, so two people saving at the
        same moment deadlocked. An event already waiting is not queued twice: views redraw from the state as it is
        when the event is delivered, so under load they redraw once per batch of changes, not once per change.
        """
        with self._pending_cv:
            self._pending[event] = None
            self._pending_cv.notify()

    def flush(self, *, timeout: float = 30.0) -> bool:
        """Wait until every event notified so far has been delivered; False on timeout."""
        with self._pending_cv:
            return self._pending_cv.wait_for(lambda: not self._pending and not self._delivering, timeout)

    def stop(self, *, wait: float | None = None) -> None:
        """Deliver nothing more (a server stopping: its pages are closing, nothing goes to them); with ``wait``, wait
        that long for a delivery in progress to end."""
        with self._pending_cv:
            self._stopped = True
            self._pending.clear()
            self._pending_cv.notify_all()
        if wait is not None and self._thread is not threading.current_thread():
            self._thread.join(wait)

    def _deliver(self) -> None:
        while True:
            with self._pending_cv:
                self._pending_cv.wait_for(lambda: self._pending or self._stopped)
                if self._stopped:
                    self._pending.clear()
                    self._pending_cv.notify_all()
                    return
                events, self._delivering = list(self._pending), True
                self._pending.clear()
            with self._lock:
                listeners = list(self._listeners)
            for event in events:
                for fn in listeners:
                    try:
                        fn(event)
                    except USER_ERRORS as exc:  # a damaged session file: one line, as everywhere
                        self._on_error(f"view update failed on {event!r}: {one_line(exc)}")
                    except Exception:  # one broken view must not stop the others
                        self._on_error(f"view update failed on {event!r}:\n{traceback.format_exc()}")
            with self._pending_cv:
                self._delivering = False
                self._pending_cv.notify_all()
