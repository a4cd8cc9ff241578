"""The browser workbench, served by viser. For now: the session's logs, terrains and labels at a glance."""

from __future__ import annotations

import html
import threading
import time
from collections.abc import Callable
from pathlib import Path

from sessions import Session

from .ui.panel_data import MAX_UPLOAD_MB, safe_name

_STYLE = (
    "<style>.wb-table{border-collapse:collapse;width:100%;font-size:0.8em;white-space:nowrap}"
    ".wb-table th,.wb-table td{padding:3px 5px;border-bottom:1px solid #e0e0e0;text-align:left}"
    ".wb-table th{color:#666;font-weight:500}"
    ".wb-table td.n,.wb-table th.n{text-align:right;font-variant-numeric:tabular-nums}"
    ".wb-chip{display:inline-block;padding:1px 6px;margin:1px;border-radius:8px;font-size:0.8em}</style>"
)


def _duration(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def logs_table_html(session: Session) -> str:
    """An HTML table of the session's logs (name, format, duration, rate, channels, labelled time)."""
    logs = session.logs()
    if not logs:
        return _STYLE + "<p>No logs yet. Ingest some with <code>workbench ingest SESSION FILE...</code></p>"
    labelled: dict[int, int] = {}
    for seg in session.segments():
        labelled[seg.log_id] = labelled.get(seg.log_id, 0) + seg.length
    rows = []
    for log in logs:
        lab = labelled.get(log.id, 0) / max(log.n_samples, 1)
        title = html.escape(f"{log.format}: {log.source_path}", quote=True)
        rows.append(
            f"<tr><td class='n'>{log.id}</td><td title='{title}'>{html.escape(log.name)}</td>"
            f"<td class='n'>{_duration(log.duration_s)}</td><td class='n'>{log.rate_hz:g}</td>"
            f"<td class='n'>{log.n_channels}</td><td class='n'>{len(log.gaps)}</td><td class='n'>{lab:.0%}</td></tr>"
        )
    total = sum(log.duration_s for log in logs)
    return (
        _STYLE
        + f"<p><b>{len(logs)}</b> logs, {_duration(total)} in all</p>"
        + "<table class='wb-table'><tr><th class='n'>#</th><th>log</th><th class='n'>length</th>"
        + "<th class='n'>Hz</th><th class='n'>channels</th><th class='n'>gaps</th><th class='n'>labelled</th></tr>"
        + "".join(rows)
        + "</table>"
    )


def terrains_html(session: Session) -> str:
    chips = "".join(
        f"<span class='wb-chip' style='background:{html.escape(t.color)}33;border:1px solid {html.escape(t.color)}'>"
        f"{i + 1} {html.escape(t.name)}</span>"
        for i, t in enumerate(session.terrains())
    )
    return _STYLE + chips


def limit_uploads(server, max_bytes: int, refused: Callable[[int, str, int], None]) -> bool:
    """Refuse an upload larger than ``max_bytes`` at its first message, before viser buffers its parts in memory.

    viser 1.1 holds a whole upload in memory before ``on_upload`` sees it, so a size check there comes after the
    harm. This wraps viser's handler of the upload's start message (its internal handler registry); the parts of a
    refused upload are then dropped as parts of an unknown transfer. Returns False, leaving the check after the
    upload as the only one, when this viser has no such registry.
    """
    from viser import _messages

    gui = server.gui
    try:
        interface, original = gui._websock_interface, gui._handle_file_transfer_start
        interface.unregister_handler(_messages.FileTransferStartUpload, original)
    except (AttributeError, AssertionError, ValueError):
        return False

    def start(client_id: int, message: _messages.FileTransferStartUpload) -> None:
        if message.size_bytes > max_bytes:
            refused(client_id, message.filename, message.size_bytes)
            return
        original(client_id, message)

    interface.register_handler(_messages.FileTransferStartUpload, start)
    return True


class WorkbenchApp:
    """A viser server over one session: shared state and training job, and one :class:`ClientView` per browser."""

    def __init__(
        self,
        session: Session,
        *,
        host: str = "127.0.0.1",
        port: int = 8080,
        hidden: int = 200,
        max_epochs: tuple[int, int] = (30, 100),
    ) -> None:
        import viser

        from training.config import TrainConfig

        from .ui.jobs import TrainJob
        from .ui.state import SharedState
        from .ui.view import ClientView

        self.session = session
        self.state = SharedState(session)
        self.job = TrainJob(
            self.state,
            hidden=hidden,
            predictor_config=TrainConfig(max_epochs=max_epochs[0], patience=5),
            classifier_config=TrainConfig(max_epochs=max_epochs[1], patience=20),
        )
        self.server = viser.ViserServer(host=host, port=port, label="Terrain workbench", verbose=False)
        self.server.gui.set_panel_label(f"Terrain workbench · {Path(session.path).name}")
        self.views: dict[int, ClientView] = {}
        self._views_lock = threading.Lock()

        def connect(client) -> None:
            view = ClientView(client, self.state, self.job)
            with self._views_lock:
                self.views[client.client_id] = view

        def disconnect(client) -> None:
            with self._views_lock:
                view = self.views.pop(client.client_id, None)
            if view is not None:
                view.close()

        self.server.on_client_connect(connect)
        self.server.on_client_disconnect(disconnect)
        limit_uploads(self.server, MAX_UPLOAD_MB << 20, self._upload_refused)
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._poll, name="session-watch", daemon=True)
        self._watch.start()

    def _upload_refused(self, client_id: int, name: str, size: int) -> None:
        client = self.server.get_clients().get(client_id)  # the client, not its view: that may still be building
        if client is not None:
            body = (f"{safe_name(name)}: {size / 2**20:.0f} MB is over the {MAX_UPLOAD_MB} MB upload limit; "
                    "ingest it with `workbench ingest` instead")  # fmt: skip
            client.add_notification("Not done", body, auto_close_seconds=8.0, color="red")

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def _fingerprint(self) -> tuple:
        history = self.session.history(limit=1)
        return (len(self.session.logs()), history[0].op_id if history else 0,
                len(self.session.segments()), tuple(v.id for v in self.session.model_versions()))  # fmt: skip

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
        self.state.stop()
        self.server.stop()

    def serve_forever(self) -> None:
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()
