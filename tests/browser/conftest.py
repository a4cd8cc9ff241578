"""Browser fixtures: a real ``workbench serve`` process on a free loopback port, and headless Debian Chromium."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

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
        return self.log_path.read_text(errors="replace")

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self._log.close()
        if "Traceback" in self.output():
            print(f"--- server output ({self.log_path}) ---\n{self.output()}")
        else:
            self.log_path.unlink(missing_ok=True)


@pytest.fixture
def serve() -> Iterator:
    servers: list[Server] = []

    def start(session: Path, *extra: str) -> Server:
        servers.append(Server(session, *extra))
        return servers[-1]

    yield start
    for s in servers:
        s.stop()


@pytest.fixture(scope="session")
def browser():
    if not Path(CHROMIUM).exists() and shutil.which("chromium") is None:
        pytest.skip("Debian chromium is not installed (make test installs it: apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the playwright Python package is not installed (pip install -e '.[dev]')")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        yield b
        b.close()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.when == "call":
        item.browser_failed = report.failed
    return report


@pytest.fixture
def page(browser, request):
    context = browser.new_context(viewport={"width": 1400, "height": 850})
    page = context.new_page()
    yield page
    if getattr(request.node, "browser_failed", False):
        save_screenshot(page, f"failed-{request.node.name}")  # what the page showed when the test failed
    context.close()


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
            tab.click(timeout=3_000)
            return
        except Exception:
            continue  # a new notification arrived over the tab
    tab.click(timeout=3_000)
