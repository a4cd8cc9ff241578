"""The suite's CPU time, printed at the end of every run beside its budget, and per test file.

Wall time says how busy the machine was that day as much as what the suite costs (the same suite took 3:45 and 9:04
on two days); user + sys CPU is what the tests ask for. Each process measures itself with ``resource.getrusage``
(its own time and that of the children it waited for: CLI calls, forked fits, the browser), pytest-xdist's workers
hand theirs to the controlling process (``workeroutput``), and each test's share rides on its teardown report, so
the files that cost most are named. ``WORKBENCH_CPU_REPORT=PATH`` also writes every file's seconds there as JSON.
The root ``tests/conftest.py`` imports these hooks.
"""

from __future__ import annotations

import json
import os
import resource
from pathlib import Path

import pytest

BUDGET_MIN = 8.0  # the suite's CPU budget: about 5 minutes of wall time on two cores on a slow day
SHOWN = 10  # test files named in the summary
FILE_CPU: dict[str, float] = {}  # test file -> CPU seconds of its tests (setup and teardown included)
WORKERS: list[float] = []  # each pytest-xdist worker's own CPU seconds, its waited-for children included


def cpu_seconds() -> float:
    """User + sys seconds of this process and of every child it has waited for."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_setup(item):
    item.cpu_at_start = cpu_seconds()
    return (yield)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.when == "teardown" and hasattr(item, "cpu_at_start"):
        report.user_properties.append(("workbench-cpu", cpu_seconds() - item.cpu_at_start))
    return report


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.when != "teardown":
        return
    for key, value in report.user_properties:
        if key == "workbench-cpu":
            path = report.nodeid.split("::")[0]
            FILE_CPU[path] = FILE_CPU.get(path, 0.0) + float(value)


def pytest_sessionfinish(session: pytest.Session) -> None:
    out = getattr(session.config, "workeroutput", None)
    if out is not None:  # a worker: the controlling process sums what each spent
        out["workbench-cpu"] = cpu_seconds()


def pytest_testnodedown(node, error) -> None:
    seconds = getattr(node, "workeroutput", {}).get("workbench-cpu")
    if seconds is not None:
        WORKERS.append(float(seconds))


def cpu_lines() -> list[str]:
    """The summary: the suite's CPU beside the budget, and the files that cost most."""
    if not FILE_CPU:
        return []
    own = resource.getrusage(resource.RUSAGE_SELF)
    total = own.ru_utime + own.ru_stime + sum(WORKERS) if WORKERS else cpu_seconds()
    tests = sum(FILE_CPU.values())
    lines = [
        f"the suite's CPU: {total / 60:.1f} min ({total:.0f} s, user + sys, every process), {tests / 60:.1f} min "
        "of it in tests; "
        f"budget {BUDGET_MIN:.0f} min ({'within' if total <= BUDGET_MIN * 60 else 'OVER'})"
    ]
    for path, seconds in sorted(FILE_CPU.items(), key=lambda kv: -kv[1])[:SHOWN]:
        lines.append(f"  {seconds:7.1f} s  {path}")
    if where := os.environ.get("WORKBENCH_CPU_REPORT"):
        Path(where).write_text(json.dumps({"total_s": total, "tests_s": tests, "files": FILE_CPU}, indent=1))
    return lines


def pytest_terminal_summary(terminalreporter) -> None:
    if lines := cpu_lines():
        terminalreporter.section("the suite's CPU")
        for line in lines:
            terminalreporter.write_line(line)
