"""Browser helpers: a real ``workbench serve`` process on a free loopback port, headless Debian Chromium, tabs.

The fixtures (``serve``, ``browser``, ``page``) live in ``tests/conftest.py``: ``tests/safety/`` drives the browser
too, and a second definition here would start a second Playwright beside the first."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from tests.conftest import REPO

CHROMIUM = os.environ.get("WORKBENCH_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
ARTIFACTS = REPO / "test-artifacts"
# How long a page may take to show what the server did. A label round trip is ~70 ms when idle, but `make test` runs
# two workers on two cores beside Chromium's software WebGL and the server, and CI machines are slower still: a
# 10 s wait failed there twice. A wait that passes returns as soon as the text shows, so a long bound costs nothing.
UI_WAIT_MS = 30_000


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Server:
    """A ``workbench serve`` subprocess; its output goes to a file (a pipe nobody reads could block it)."""

    def __init__(self, session: Path, *extra: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        self._final: str | None = None
        self.log_path = Path(tempfile.mkstemp(prefix="workbench-serve-", suffix=".log")[1])
        self._log = self.log_path.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "workbench.cli", "serve", str(session), "--port", str(self.port), *extra],
            stdout=self._log,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
        )
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if "workbench serving" in self.output():
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        self.stop()
        raise RuntimeError(f"server did not start (exit {self.proc.returncode}):\n{self.output()}")

    def output(self) -> str:
        """What the server printed (kept once it stopped, when its log file is gone)."""
        if self._final is not None:
            return self._final
        return self.log_path.read_text(errors="replace")

    def stop(self) -> None:
        """SIGTERM, then SIGKILL after 10 s; a second call does nothing."""
        if self._final is not None:
            return
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._log.close()
        self._final = self.output()
        if "Traceback" in self._final:
            print(f"--- server output ({self.log_path}) ---\n{self._final}")
        else:
            self.log_path.unlink(missing_ok=True)


@contextlib.contextmanager
def shared_page(
    source: Path, folder: Path, browser, *extra: str, before: Callable[[Path], Any] | None = None
) -> Iterator[tuple[Path, Any, Server, Any]]:
    """A copy of the session ``source`` at ``folder / "s"``, a ``workbench serve`` on it and one page (not opened),
    for a module's tests to share in file order (a file runs on one pytest worker, in order): a page load is 5 s of
    software WebGL in headless Chromium. ``before`` reads the copy before the server starts; its result comes
    second."""
    path = folder / "s"
    shutil.copytree(source, path)
    seen = before(path) if before is not None else None
    server = Server(path, *extra)
    context = browser.new_context(viewport={"width": 1400, "height": 850})
    try:
        yield path, seen, server, context.new_page()
    finally:
        context.close()
        server.stop()


def save_screenshot(page, name: str) -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path))
    return path


def close_notifications(page) -> None:
    """Close every notification with its close button, as a person does.

    viser shows notifications over the top of the panels, and Mantine pauses a notification's timer while the
    pointer is over it, so one that covers a tab never leaves while a click waits on that tab.
    """
    buttons = page.locator("div.mantine-Notification-root button")
    for _ in range(20):
        if buttons.count() == 0:
            return
        with contextlib.suppress(Exception):  # it closed by itself between the count and the click
            buttons.first.click(timeout=1_000)


def open_tab(page, name: str) -> None:
    """Click a tab of the control panel, closing the notifications that cover it first."""
    tab = page.get_by_role("tab", name=name)
    for _ in range(5):
        close_notifications(page)
        try:
            tab.click(timeout=5_000)
            return
        except Exception:
            continue  # a new notification arrived over the tab
    tab.click(timeout=UI_WAIT_MS)
