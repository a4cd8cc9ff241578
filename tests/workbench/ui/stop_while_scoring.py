"""Serve a session several times in this process, each time stopped by a signal while the refresh is known to be
scoring on the torch lane, a client connected: what ``test_quiet_stop.py`` reads from this process's output.

Usage: ``python stop_while_scoring.py SESSION TIMES``. Odd rounds send SIGINT (Ctrl+C), even ones SIGTERM; each round
prints ``stopped N in S s`` once ``serve_forever`` returned.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import socket
import sys
import threading
import time
import traceback
import warnings
from pathlib import Path

from sessions import Session
from tests.safety.viser_client import ViserClient
from workbench.ui import LANE, WorkbenchApp
from workbench.ui import state as state_module

REAL = state_module.compute_scores
SCORING = threading.Event()


def scoring_on_the_lane(*args, **kwargs):
    """The real scoring, then a moment on the lane for the signal to land in (the scoring's own time, made sure)."""
    out = REAL(*args, **kwargs)
    SCORING.set()
    time.sleep(0.25)
    return out


def read_all(client: ViserClient) -> None:
    """Read what the server sends, as a browser does (a client that reads nothing holds the server's close)."""
    with contextlib.suppress(Exception):
        while True:
            client.ws.recv()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def warning_with_its_stack(message, category, filename, lineno, file=None, line=None) -> None:
    """A warning with where it was raised from, so a failing test says which update came after the stop."""
    print(f"{filename}:{lineno}: {category.__name__}: {message}", file=sys.stderr)
    traceback.print_stack(file=sys.stderr)


def main(path: Path, times: int) -> None:
    warnings.showwarning = warning_with_its_stack
    state_module.compute_scores = scoring_on_the_lane  # the worker looks it up at each call
    for i in range(times):
        for kept in (path / "cache").glob("scores-*"):  # no kept scores: the refresh scores every log again
            shutil.rmtree(kept) if kept.is_dir() else kept.unlink()
        SCORING.clear()
        signum = signal.SIGINT if i % 2 else signal.SIGTERM
        with Session.open(path) as s:
            LANE.expect()
            app = WorkbenchApp(s, port=free_port(), token="t" * 32)
            client = ViserClient(app.url)
            threading.Thread(target=read_all, args=(client,), daemon=True).start()

            def fire(signum: int = signum, t0: float = time.monotonic()) -> None:
                if SCORING.wait(60):
                    print(f"signal at {time.monotonic() - t0:.1f} s", flush=True)
                    os.kill(os.getpid(), signum)

            t0 = time.monotonic()
            threading.Thread(target=fire, daemon=True).start()
            app.serve_forever()
            client.close()
        print(f"stopped {i} by {signal.Signals(signum).name} in {time.monotonic() - t0:.1f} s", flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]))
