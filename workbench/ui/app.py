"""The browser workbench, served by viser: one server over a session, a view per browser, the session watched for
changes made by other processes."""

from __future__ import annotations

import signal
import sqlite3
import threading
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
    ) -> None:
        from .gate import Gate
        from .jobs import TrainJob
        from .state import SharedState
        from .view import ClientView

        # the gate first: a taken port is refused before anything else starts
        self.gate = Gate(host=host, port=port, token=token)
        self.session = session
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
            if self._stop.is_set():
                return  # the server is stopping: a page that connects now has nothing to be built from
            limit_uploads(client, self.uploads, self._upload_refused)  # before its upload button exists
            try:
                view = ClientView(client, self.state, self.job)
            except sqlite3.ProgrammingError:
                # the session closed under a page still being built (a stop racing a connect): nothing to show,
                # and no traceback on the terminal of someone who pressed Ctrl+C
                if self._stop.is_set():
                    return
                raise
            with self._views_lock:
                self.views[client.client_id] = view

        def disconnect(client) -> None:
            self.uploads.release_client(client.client_id)  # viser drops the buffers; their room comes back
            with self._views_lock:
                view = self.views.pop(client.client_id, None)
            if view is not None:
                view.close()

        self.server.on_client_connect(connect)
        self.server.on_client_disconnect(disconnect)
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._poll, name="session-watch", daemon=True)
        self._watch.start()

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

    def _fingerprint(self) -> tuple:
        history = self.session.history(limit=1)
        return (
            len(self.session.logs()),
            history[0].op_id if history else 0,
            len(self.session.segments()),
            tuple(v.id for v in self.session.model_versions()),
        )

    def _poll(self) -> None:
        # Another process (a CLI ingest, import or train) may change the session: follow it.
        last = self._fingerprint()
        while not self._stop.wait(2.0):
            try:
                now = self._fingerprint()
            except Exception:
                continue
            if now == last:
                continue
            if now[0] != last[0]:
                self.state.logs_changed()
            if now[1:3] != last[1:3]:
                self.state.notify("labels")
                self.state.refresh(scores=False)
            if now[3] != last[3] and not self.job.running:
                self.state.notify("models")
                self.state.refresh(scores=True)
            last = now

    def stop(self) -> None:
        self._stop.set()
        self.gate.stop()
        self.state.stop()
        self.server.stop()
        remove_private_socket(self._inner)

    def serve_forever(self) -> None:
        """Serve until Ctrl+C or SIGTERM; this thread runs every PyTorch call of the server
        (``workbench.ui.torch_lane``)."""
        # SIGTERM (systemd, `docker stop`, `kill`, a test harness) stops as Ctrl+C does: without it Python dies
        # at once and leaves the private socket's folder behind in the temp directory, one per server
        previous = _stop_on_sigterm()
        try:
            LANE.serve(stop=self._stop.is_set)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()
            if previous is not None:
                signal.signal(signal.SIGTERM, previous)


def _stop_on_sigterm() -> Any:
    """Make SIGTERM raise ``KeyboardInterrupt`` in this (the main) thread; the handler it replaced, or ``None``
    where signals cannot be set here (not the main thread)."""

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, interrupt)
