"""The safety tests' fixtures: ``promise``, ``detail`` and ``hostile_case`` report figures for the summary that
``tests/promise_report.py`` prints (one line per promise at the end of the run), and ``served`` starts a real
``workbench serve`` in a child."""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.conftest import new_session

SERVE_TOKEN = "t0ken-for-the-safety-tests"


# Tests report through their reports' user properties, which reach this process from pytest-xdist's workers too.
@pytest.fixture
def detail(request):
    """Call with a measured figure to append to the line of the test's module."""
    return lambda text: request.node.user_properties.append(("workbench-detail", text))


@pytest.fixture
def promise(request):
    """Call with the test's summary line."""
    return lambda text: request.node.user_properties.append(("workbench-promise", text))


@pytest.fixture
def hostile_case(request):
    """Call with a hostile case's name, seconds, peak MB and exit code: the summary line counts them."""
    return lambda *case: request.node.user_properties.append(("workbench-hostile", case))


@pytest.fixture
def served(tmp_path: Path):
    """``workbench serve SESSION --token T --port 0`` in a child, as a user starts it; yields (process, gate port,
    everything it printed up to its URL). The token is ``SERVE_TOKEN``."""
    new_session(tmp_path / "s").close()
    proc = subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", "serve", str(tmp_path / "s"), "--token", SERVE_TOKEN, "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        banner = ""
        while "workbench serving" not in banner:  # everything printed up to the URL
            line = proc.stdout.readline()
            assert line, f"serve ended before it served: {banner}"
            banner += line
        port = int(banner.rsplit("http://127.0.0.1:", 1)[1].split("/")[0])
        # what it prints later is read, so that a full pipe never blocks the server
        threading.Thread(target=proc.stdout.read, daemon=True).start()
        yield proc, port, banner
    finally:
        proc.terminate()
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
