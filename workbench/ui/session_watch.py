"""Following a session that another process changes (a CLI ingest, import or train): the page and the Label Studio
backend both serve a session the person may change from a terminal meanwhile."""

from __future__ import annotations

import threading
from collections.abc import Callable

from sessions import Session

from .state import SharedState

POLL_S = 2.0  # a change made elsewhere is seen within this long


def session_fingerprint(session: Session) -> tuple:
    """What changes when another process adds a log, changes labels or registers a model."""
    history = session.history(limit=1)
    return (
        len(session.logs()),
        history[0].op_id if history else 0,
        len(session.segments()),
        tuple(v.id for v in session.model_versions()),
    )


def watch_session(state: SharedState, *, stop: threading.Event, training: Callable[[], bool]) -> threading.Thread:
    """Start a daemon thread that polls the session until ``stop`` is set and tells ``state`` what changed: new logs
    (the catalog reloaded and rescored), labels (the queue), models (rescored; not while this process's own
    ``training()`` is registering them)."""

    def poll() -> None:
        last = session_fingerprint(state.session)
        while not stop.wait(POLL_S):
            try:
                now = session_fingerprint(state.session)
            except Exception:  # a session busy or briefly unreadable: the next poll sees it
                continue
            if now == last:
                continue
            if now[0] != last[0]:
                state.logs_changed()
            if now[1:3] != last[1:3]:
                state.notify("labels")
                state.refresh(scores=False)
            if now[3] != last[3] and not training():
                state.notify("models")
                state.refresh(scores=True)
            last = now

    thread = threading.Thread(target=poll, name="session-watch", daemon=True)
    thread.start()
    return thread
