"""The safety tests' summary: each promise gets a line (tries, failures, labels checked) at the end of the run, so
``make stress`` ends with a line per promise. Tests that measure report their own line through ``promise``; the
others are counted here by module."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from tests.conftest import new_session

SERVE_TOKEN = "t0ken-for-the-safety-tests"
LINES: list[str] = []
COUNTED = {  # module -> the promise its tests check
    "test_kill_training": "promise 2 (training killed at any moment)",
    "test_fuzz_readers": "promise 3 (fuzz targets: the MCAP and CSV readers, Label Studio import)",
    "test_safe_defaults": "promise 5 (safe by default: loopback, upload limit and names, no pickle, newer schema)",
    "test_disk_full": "promise 6 (full and read-only disk: labels and models, store, CLI and UI)",
    "test_bombs": "promise 8 (bombs: decoded bytes and pixels bounded in every reader, the CLI and uploads)",
    "test_upload_totals": "upload totals (one total for the server, two at once per page, memory back when a page "
    "leaves)",
    "test_terminal_names": "names escaped (terminal control characters in names, the dry run's mapping round trip)",
    "test_security": "promise 7 (security: same origin and token, escaped names, uploads cut at the limit, label "
    "import, CSV formulas, tampered files, taken port)",
}
DETAILS: dict[str, list[str]] = {}  # module -> figures its tests measured, appended to its line
COUNTS: dict[str, list[int]] = {}  # module -> [tests, failures]


@pytest.fixture
def detail(request):
    """Call with a measured figure to append to the line of the test's module."""
    module = Path(str(request.node.fspath)).stem
    return DETAILS.setdefault(module, []).append


@pytest.fixture
def promise():
    """Call with the test's summary line."""
    return LINES.append


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    module = Path(report.nodeid.split("::")[0]).stem
    if module not in COUNTED or report.skipped:
        return
    if report.when == "call" or (report.when == "setup" and report.failed):
        counts = COUNTS.setdefault(module, [0, 0])
        counts[0] += 1
        counts[1] += int(report.failed)


def pytest_terminal_summary(terminalreporter) -> None:
    lines = list(LINES)
    for module, (tests, failures) in sorted(COUNTS.items(), key=lambda kv: COUNTED[kv[0]]):
        extra = f", {os.environ.get('WORKBENCH_FUZZ_EXAMPLES', '40')} examples each" if "fuzz" in module else ""
        figures = "".join(f"; {d}" for d in DETAILS.get(module, []))
        lines.append(f"{COUNTED[module]}: {tests} tests{extra}, {failures} failures{figures}")
    if lines:
        terminalreporter.section("promises (issue 7)")
        for line in sorted(lines, key=lambda s: s.split(":")[0]):
            terminalreporter.write_line(line)


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
