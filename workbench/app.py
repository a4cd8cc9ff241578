"""The browser workbench, served by viser. For now: the session's logs, terrains and labels at a glance."""

from __future__ import annotations

import html
import threading
import time
from pathlib import Path

from sessions import Session

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


class WorkbenchApp:
    """A viser server over one session; the page refreshes its lists when the session changes."""

    def __init__(self, session: Session, *, host: str = "127.0.0.1", port: int = 8080) -> None:
        import viser

        self.session = session
        self.server = viser.ViserServer(host=host, port=port, label="Terrain workbench", verbose=False)
        gui = self.server.gui
        gui.configure_theme(
            titlebar_content=None,
            control_layout="fixed",
            control_width="large",
            show_logo=False,
            show_share_button=False,
            brand_color=(46, 125, 50),
        )
        gui.add_markdown(f"## Terrain workbench\nSession `{html.escape(Path(session.path).name)}`")
        with gui.add_folder("Logs"):
            self._logs = gui.add_html(logs_table_html(session))
        with gui.add_folder("Terrains"):
            self._terrains = gui.add_html(terrains_html(session))
        self._stop = threading.Event()
        self._watch = threading.Thread(target=self._poll, name="session-watch", daemon=True)
        self._watch.start()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    def _poll(self) -> None:
        # Another process (a CLI ingest) may change the session: refresh what the page shows.
        last = (self._logs.content, self._terrains.content)
        while not self._stop.wait(2.0):
            try:
                now = (logs_table_html(self.session), terrains_html(self.session))
            except Exception:
                continue
            if now != last:
                self._logs.content, self._terrains.content = now
                last = now

    def stop(self) -> None:
        self._stop.set()
        self.server.stop()

    def serve_forever(self) -> None:
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            self.stop()
