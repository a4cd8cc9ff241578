"""The browser workbench, served by viser: one server over a session, a view per browser, the session watched for
changes made by other processes."""

from __future__ import annotations

import signal
import sqlite3
import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from sessions import Session

from ..retrain import RETRAIN
from .private_viser import remove_private_socket, start_private_viser
from .torch_lane import LANE
from .uploads import UploadBudget, limit_uploads


class WorkbenchApp:
    """A viser server over one session: shared state and training job, and one :class:`ClientView` per browser."""

    def __init__(
        self,
        session: Session,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        token: str | None = None,
        hidden: int = RETRAIN.hidden,
        max_epochs: tuple[int, int] = (RETRAIN.predictor.max_epochs, RETRAIN.classifier.max_epochs),
        open_map: bool = False,
    ) -> None:
        from .gate import Gate
        from .jobs import TrainJob
        from .session_watch import watch_session
        from .state import SharedState
        from .view import ClientView

        # the gate first: a taken port is refused before anything else starts
        self.gate = Gate(host=host, port=port, token=token)
        self.session = session
        self.open_map = open_map  # pages open on the map where the log has positions
        self.state = SharedState(session)
        self.job = TrainJob(
            self.state,
            hidden=hidden,
            predictor_config=replace(RETRAIN.predictor, max_epochs=max_epochs[0]),
            classifier_config=replace(RETRAIN.classifier, max_epochs=max_epochs[1]),
        )
        # viser serves on a private Unix socket with a secret; people reach it only through the gate
        self.server, self._inner = start_private_viser(label="Terrain workbench", verbose=False)
        self.gate.inner = self._inner
        self.server.gui.set_panel_label(f"Terrain workbench · {Path(session.path).name}")
        self.views: dict[int, ClientView] = {}
        self._views_lock = threading.Lock()
        self.uploads = UploadBudget()  # what every client together may be sending at once

        def connect(client) -> None:
            with self._building:
                if self._stop.is_set():
                    return  # the server is stopping: a page that connects now has nothing to be built from
                self._pages_building += 1
            try:
                limit_uploads(client, self.uploads, self._upload_refused)  # before its upload button exists
                view = ClientView(client, self.state, self.job, open_map=self.open_map)
            except sqlite3.ProgrammingError:
                # the session closed under a page still being built (a stop racing a connect): nothing to show,
                # and no traceback on the terminal of someone who pressed Ctrl+C
                if self._stop.is_set():
                    return
                raise
            finally:
                with self._building:
                    self._pages_building -= 1
                    self._building.notify_all()
            with self._views_lock:
                self.views[client.client_id] = view

        def disconnect(client) -> None:
            self.uploads.release_client(client.client_id)  # viser drops the buffers; their room comes back
            with self._views_lock:
                view = self.views.pop(client.client_id, None)
            if view is not None:
                view.close()

        self._stop = threading.Event()
        # pages being built: a stop waits for them, as a page built over a closed connection is written to nothing
        self._building = threading.Condition()
        self._pages_building = 0
        self.server.on_client_connect(connect)
        self.server.on_client_disconnect(disconnect)
        self._watch = watch_session(self.state, stop=self._stop, training=lambda: self.job.running)

    def _upload_refused(self, client_id: int, why: str) -> None:
        client = self.server.get_clients().get(client_id)  # the client, not its view: that may still be building
        if client is not None:
            body = f"Upload refused: {why}. Large logs ingest with `workbench ingest`."
            client.add_notification("Not done", body, auto_close_seconds=8.0, color="red")

    @property
    def url(self) -> str:
        """The address to open, with the token when the server has one."""
        host = self.gate.host if ":" not in self.gate.host else f"[{self.gate.host}]"
        query = f"/?token={self.gate.token}" if self.gate.token else ""
        return f"http://{host}:{self.gate.port}{query}"

    def request_stop(self) -> None:
        """Ask the server to stop (Ctrl+C, SIGTERM): every worker polls the flag and ends its work where it can, a
        training run is cancelled, and :meth:`serve_forever` returns once the torch lane's current call is done."""
        self._stop.set()
        self.job.cancel()
        self.state.request_stop()

    def stop(self) -> None:
        """Stop everything: the workers first, so no view is sent anything once its connection closes; then the
        gate and viser."""
        self.request_stop()
        with self._building:
            self._building.wait_for(lambda: self._pages_building == 0, timeout=30.0)
        self.job.join()
        self.state.stop()
        self.gate.stop()
        self.server.stop()
        remove_private_socket(self._inner)

    def serve_forever(self) -> None:
        """Serve until Ctrl+C or SIGTERM; this thread runs every PyTorch call of the server
        (``workbench.ui.torch_lane``)."""
        # Ctrl+C and SIGTERM (systemd, `docker stop`, `kill`) set the stop flag the workers poll. Raising
        # KeyboardInterrupt here, as Python does by default, raised it inside whatever torch call the lane was
        # running for another thread, which printed that thread's traceback; without a handler SIGTERM killed the
        # process at once, leaving the private socket's folder behind. A second Ctrl+C stops at once.
        previous = _on_stop_signals(self.request_stop, again=self._stop.is_set)
        try:
            LANE.serve(stop=self._stop.is_set)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()
            for signum, handler in previous.items():
                signal.signal(signum, handler)


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _on_stop_signals(stop: Callable[[], None], *, again: Callable[[], bool]) -> dict[int, Any]:
    """Make Ctrl+C and SIGTERM call ``stop`` in this (the main) thread, and raise ``KeyboardInterrupt`` when they come
    while ``again()`` (stopping already); the handlers they replaced, none where signals cannot be set here (not
    the main thread)."""

    def handler(signum: int, frame: Any) -> None:
        if again():
            raise KeyboardInterrupt
        stop()

    if threading.current_thread() is not threading.main_thread():
        return {}
    return {signum: signal.signal(signum, handler) for signum in STOP_SIGNALS}
