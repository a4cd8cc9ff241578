"""The safety tests' summary: each promise gets a line (tries, failures, labels checked) at the end of the run, so
``make stress`` ends with a line per promise. Tests that measure report their own line through the ``promise``,
``detail`` and ``hostile_case`` fixtures (``tests/safety/conftest.py``) as user properties of their reports, which
reach the controlling process from pytest-xdist's workers too; the others are counted here by module. The root
``tests/conftest.py`` imports these hooks: it is the conftest the controlling process loads.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

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
HOSTILE: list[tuple[str, float, float, int]] = []  # (case, seconds, peak MB, exit code) of test_hostile_cli's cases


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    module = Path(report.nodeid.split("::")[0]).stem
    if report.when == "teardown":  # its report carries every property the test added, in any phase
        for key, value in report.user_properties:
            if key == "workbench-detail":
                DETAILS.setdefault(module, []).append(value)
            elif key == "workbench-promise":
                LINES.append(value)
            elif key == "workbench-hostile":
                HOSTILE.append(tuple(value))
    if module not in COUNTED or report.skipped:
        return
    if report.when == "call" or (report.when == "setup" and report.failed):
        counts = COUNTS.setdefault(module, [0, 0])
        counts[0] += 1
        counts[1] += int(report.failed)


def _hostile_lines() -> list[str]:
    if not HOSTILE:
        return []
    slowest, highest = max(HOSTILE, key=lambda m: m[1]), max(HOSTILE, key=lambda m: m[2])
    lines = [
        f"hostile input through the CLI (issue 52): {len(HOSTILE)} cases, each one line and exit 2 or read "
        f"correctly; slowest {slowest[1]:.1f} s ({slowest[0]}), highest peak RSS {highest[2]:.0f} MB ({highest[0]}); "
        "limits 20 s and 1024 MB"
    ]
    if os.environ.get("WORKBENCH_HOSTILE_TABLE"):  # the table of issue 52's closing note
        lines += [
            f"hostile case | {name} | exit {code} | {seconds:.1f} s | {peak:.0f} MB"
            for name, seconds, peak, code in HOSTILE
        ]
    return lines


def pytest_terminal_summary(terminalreporter) -> None:
    lines = list(LINES) + _hostile_lines()
    for module, (tests, failures) in sorted(COUNTS.items(), key=lambda kv: COUNTED[kv[0]]):
        extra = f", {os.environ.get('WORKBENCH_FUZZ_EXAMPLES', '40')} examples each" if "fuzz" in module else ""
        figures = "".join(f"; {d}" for d in DETAILS.get(module, []))
        lines.append(f"{COUNTED[module]}: {tests} tests{extra}, {failures} failures{figures}")
    if lines:
        terminalreporter.section("promises (issue 7)")
        for line in sorted(lines, key=lambda s: s.split(":")[0]):
            terminalreporter.write_line(line)
