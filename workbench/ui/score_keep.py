"""Score every log and rank the queue once, kept in the session, before a page opens (``workbench demo``)."""

from __future__ import annotations

import threading

from sessions import Session

from .state import SharedState
from .torch_lane import LANE


def score_and_keep(session: Session, *, timeout_s: float = 3600.0) -> bool:
    """Score every log and rank the suggestion queue once, kept in the session, so the page's first screen draws
    them at once (``workbench demo`` does this before serving). The calling thread runs the torch work (it may have
    trained already: see ``workbench.ui.torch_lane``). Returns False when it did not finish in time."""
    errors: list[str] = []
    finished: list[bool] = []

    def score() -> None:
        state = SharedState(session, on_error=errors.append)
        try:
            finished.append(state.wait_idle(stop=lambda: False, deadline_s=timeout_s))
        finally:
            state.stop()

    waiter = threading.Thread(target=score, name="score-and-keep", daemon=True)
    if LANE.serving:
        waiter.start()
    else:  # the worker's torch work comes to this thread
        LANE.serve(stop=lambda: not waiter.is_alive(), started=waiter.start)
    waiter.join()
    return bool(finished and finished[0]) and not errors
