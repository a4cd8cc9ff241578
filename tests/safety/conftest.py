"""The safety tests' summary: each promise's test reports one line (tries, failures, labels checked), printed at the
end of the run, so ``make stress`` ends with a line per promise."""

from __future__ import annotations

import pytest

LINES: list[str] = []


@pytest.fixture
def promise():
    """Call with the test's summary line."""
    return LINES.append


def pytest_terminal_summary(terminalreporter) -> None:
    if LINES:
        terminalreporter.section("promises (issue 7)")
        for line in LINES:
            terminalreporter.write_line(line)
