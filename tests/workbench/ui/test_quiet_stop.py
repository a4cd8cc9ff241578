"""Ctrl+C and SIGTERM stop the server quietly while the refresh is scoring on the torch lane: what an idle stop
prints, nothing more (no traceback from the refresh thread, no viser warning about a closed connection)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO
from tests.workbench.evaluation.test_session_loop import _walk, walk_session
from workbench.cli import main

pytestmark = pytest.mark.usefixtures("fast_window_fits")

TIMES = 20  # stops in a row, SIGTERM and SIGINT by turns, each while a refresh is known to be scoring


def test_a_stop_while_the_refresh_scores_is_quiet_every_time(tmp_path: Path, quick_stage1) -> None:
    session, _ = walk_session(tmp_path, [_walk(tmp_path / f"w{i}.csv", i, seconds=30.0) for i in range(2)])
    assert main(["train", str(session)]) == 0
    child = subprocess.run(
        [sys.executable, str(Path(__file__).with_name("stop_while_scoring.py")), str(session), str(TIMES)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    out = child.stdout + child.stderr
    assert child.returncode == 0, out
    stops = [line for line in out.splitlines() if line.startswith("stopped ")]
    assert len(stops) == TIMES, out
    others = [
        line
        for line in out.splitlines()
        if line.strip() and not line.startswith(("stopped ", "signal at ", "(viser) Server stopped"))
    ]
    assert not others, "\n".join(others)  # an idle stop prints "(viser) Server stopped" and nothing else
