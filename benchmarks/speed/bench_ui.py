"""UI: open a 1-hour, 22-channel, 100 Hz log and draw its first window; pan and zoom.

Timed end to end on a real server and a real browser: ``WorkbenchApp`` in this process, headless Chromium connected
to it. Each action is called on the browser's view on the server (what the log dropdown, Shift+→ and ↓ call); the
time runs from the call to the last websocket frame of the redraw arriving in the page (stamped in the page with
the wall clock, which both share), so it covers reading the memory-mapped log, decimating, building the charts,
viser's serialisation and the socket. The reference beside it is the same action with decimation off: every sample
of the window sent raw.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from speed_common import Row, fmt_s, free_port, parse_args, record

from sessions import Session
from workbench.demo import generate_walk, write_walk

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


class Probe:
    """Times server-side actions until their frames have arrived at the browser.

    viser's client opens its socket in a web worker; Playwright reports that socket's frames, and each is stamped
    here when Playwright hands it over (while this thread waits in ``wait_for_timeout``), so a stamp is never earlier
    than the frame's arrival.
    """

    def __init__(self, page, view) -> None:
        self.page, self.view = page, view
        self.quiet_s = 0.4  # a redraw's frames come within this of each other
        self.frames: list[tuple[float, int]] = []
        page.on("websocket", lambda ws: ws.on("framereceived", self._on_frame))

    def _on_frame(self, payload) -> None:
        self.frames.append((time.time(), len(payload)))

    def settle(self, quiet_s: float | None = None, limit_s: float = 120.0) -> list[tuple[float, int]]:
        """Wait until no frame has arrived for ``quiet_s``; the frames since the last call."""
        quiet_s = self.quiet_s if quiet_s is None else quiet_s
        deadline = time.monotonic() + limit_s
        seen, last_change = -1, time.monotonic()
        while time.monotonic() < deadline:
            if len(self.frames) != seen:
                seen, last_change = len(self.frames), time.monotonic()
            elif time.monotonic() - last_change >= quiet_s:
                break
            self.page.wait_for_timeout(5)
        out, self.frames = self.frames, []
        return out

    def __call__(self, action: Callable[[], None]) -> tuple[float, float, int]:
        """Seconds from the call to the last frame, seconds on the server, bytes received."""
        self.settle()
        t0 = time.time()
        with self.view._lock:
            action()
        server = time.time() - t0
        frames = self.settle()
        if not frames:
            return server, server, 0
        return max(f[0] for f in frames) - t0, server, int(sum(f[1] for f in frames))


def run_actions(probe: Probe, view, big, small, *, opens: int, pans: int) -> dict[str, list]:
    out: dict[str, list] = {"open": [], "pan": [], "zoom": []}
    for _ in range(opens):
        probe(lambda: view.show(small))
        out["open"].append(probe(lambda: view.show(big)))
    view.set_widget(view.zoom, "5 min")  # as if picked in the Window dropdown
    view.set_width(300.0)
    for i in range(pans):  # right and back: every pan moves the window, whatever the log's length
        out["pan"].append(probe(lambda d=(1.0 if i % 2 == 0 else -1.0): view.step(d)))
    for steps in (1, 1, 1, 1, -1, -1, -1, -1):  # 5 min -> 1 h and back
        out["zoom"].append(probe(lambda s=steps: view.zoom_by(s)))
    return out


def main() -> None:
    args = parse_args(__doc__)
    from playwright.sync_api import sync_playwright

    from workbench.ui import WorkbenchApp

    minutes = 10.0 if args.quick else 60.0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        small_path = write_walk(generate_walk(1, 20.0), folder / "a_short.mcap")
        big_path = write_walk(generate_walk(0, minutes * 60.0), folder / "b_hour.mcap")
        session = Session.create(folder / "session")
        small, big = session.ingest([small_path, big_path])
        assert big.n_samples >= 0.999 * minutes * 6000 and len(big.channel_names) == 22, big.n_samples
        app = WorkbenchApp(session, port=free_port())
        try:
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_FLAGS)
                page = browser.new_page(viewport={"width": 1500, "height": 950})
                probe = Probe(page, None)
                page.goto(app.url)
                deadline = time.monotonic() + 60
                while not app.views and time.monotonic() < deadline:
                    page.wait_for_timeout(100)
                (view,) = app.views.values()
                probe.view = view
                probe.settle(quiet_s=1.0)
                ours = run_actions(probe, view, big, small, opens=5, pans=10)
                view.pixels = 10**9  # the reference: every sample of the window, raw
                probe.quiet_s = 3.0  # serialising a raw hour takes seconds before its frame leaves
                raw = run_actions(probe, view, big, small, opens=3, pans=3)
                view.pixels = 1100
                shown = page.evaluate("document.body.innerText")
                browser.close()
        finally:
            app.stop()
    ok = "b_hour" in shown
    rows = []
    for name, label, target, limit in (
        ("open", f"UI: open a {minutes:.0f}-min 22-channel 100 Hz log, first 30 s window in the browser", "≤ 1 s", 1.0),
        ("pan", "UI: pan one 5-min window (Shift+→ / Shift+←)", "≤ 150 ms", 0.15),
        ("zoom", "UI: zoom 5 min ↔ 1 h, one step (↑/↓)", "≤ 150 ms", 0.15),
    ):
        a, r = np.array(ours[name]), np.array(raw[name])
        p50, worst = np.median(a[:, 0]), a[:, 0].max()
        check = f"server part {fmt_s(np.median(a[:, 1]))}; page shows the log: {'yes' if ok else '**no**'}"
        rows.append(
            Row(
                f"{label} (median / worst of {len(a)})",
                f"{fmt_s(p50)} / {fmt_s(worst)}",
                f"raw window sent: {fmt_s(np.median(r[:, 0]))} ({np.median(r[:, 2]) / 1e6:.1f} MB)",
                f"{np.median(r[:, 0]) / p50:.1f}× faster; {np.median(a[:, 2]) / 1e3:.0f} kB sent",
                target,
                bool(worst <= limit),
                check,
            )
        )
    record("ui", rows, device=args.device)


if __name__ == "__main__":
    main()
