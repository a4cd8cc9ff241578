"""``workbench label-studio``: the backend's state, training job and server, until Ctrl+C or SIGTERM."""

from __future__ import annotations

import signal
import threading

from sessions import Session, WorkbenchError

from ..retrain import RETRAIN
from ..ui import LANE, SharedState, TrainJob, watch_session
from .backend import Backend
from .http_server import BackendServer


def serve_label_studio(
    session: Session,
    *,
    host: str,
    port: int,
    auth: tuple[str, str] | None,
    create_terrains: bool = False,
    hidden: int = RETRAIN.hidden,
    ready: threading.Event | None = None,
    stop: threading.Event | None = None,
) -> None:
    """Serve ``session`` to Label Studio; this thread runs the torch work (scoring, Retrains) as ``serve`` does.

    Args:
        session: The session (open; closed by the caller).
        host: Address to bind.
        port: Port (0: any free one, printed).
        auth: Basic auth's user and password, or ``None`` (loopback only: the caller checks).
        create_terrains: A terrain Label Studio names that the session lacks is added.
        hidden: LSTM width of a predictor a Retrain trains (the paper family's; as ``serve``'s).
        ready: Set once the server answers (tests).
        stop: Set to stop (tests); Ctrl+C and SIGTERM stop it otherwise.
    """
    stop = stop or threading.Event()
    LANE.expect()
    state = SharedState(session)
    job = TrainJob(state, hidden=hidden)
    backend = Backend(
        state, start_training=lambda: job.start(), job_status=lambda: job.status, create_terrains=create_terrains
    )
    try:
        server = BackendServer(backend, host=host, port=port, auth=auth)
    except OSError as exc:  # the port is taken, or the address is not this machine's
        LANE.expect_no_more()
        state.stop()
        raise WorkbenchError(f"cannot listen on {host}:{port} ({exc.strerror or exc})") from None
    except BaseException:
        LANE.expect_no_more()
        state.stop()
        raise
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    server.start()
    watch_session(state, stop=stop, training=lambda: job.running)  # a CLI ingest or train meanwhile: followed
    print(f"workbench label-studio: {session.path} served as an ML backend at {server.url}", flush=True)
    if ready is not None:
        ready.set()
    try:
        LANE.serve(stop=stop.is_set)
    finally:
        server.stop()
        job.join()
        state.stop()
        for s, handler in previous.items():
            signal.signal(s, handler)
