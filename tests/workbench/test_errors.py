"""One error family: a damaged model reaches the CLI and the UI as one clear line, never as an internal error."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from sessions import Session, WorkbenchError
from tests.workbench.cycle.test_cycle import TINY, demo_logs, trained, trained_once  # noqa: F401  (fixtures)
from training import BundleError, TrainingError
from workbench.cli import main
from workbench.ui import SharedState
from workbench.user_errors import USER_ERRORS, one_line


def damage_active_classifier(session: Session) -> Path:
    """Overwrite the active classifier's weights with bytes that are no safetensors file; returns its folder."""
    version = session.active_model("classifier")
    assert version is not None
    folder = session.path / version.path
    weights = sorted(folder.glob("*.safetensors"))
    assert weights, f"no weights in {folder}"
    for w in weights:
        w.write_bytes(b"\x00not a safetensors file" * 8)
    return folder


def error_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.strip()]


def test_the_family_is_what_the_cli_and_the_ui_catch() -> None:
    assert issubclass(BundleError, TrainingError) and TrainingError in USER_ERRORS and WorkbenchError in USER_ERRORS
    assert one_line(ValueError("a\n  b\tc")) == "a b c"


def test_damaged_weights_reach_export_classify_and_the_ui_as_one_line(
    trained: Session,  # noqa: F811
    demo_logs: list[Path],  # noqa: F811
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
) -> None:
    folder = damage_active_classifier(trained)
    capsys.readouterr()

    assert main(["export", str(trained.path), "--out", str(tmp_path / "out")]) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and "damaged model bundle" in err[0] and str(folder) in err[0], err
    assert "internal error" not in err[0] and not (tmp_path / "out").exists()

    assert main(["classify", str(folder), str(demo_logs[0]), "--out", str(tmp_path / "p.csv")]) == 2
    err = error_lines(capsys.readouterr().err)
    assert len(err) == 1 and "damaged model bundle" in err[0] and "internal error" not in err[0], err
    assert not (tmp_path / "p.csv").exists()

    printed: list[str] = []
    state = SharedState(trained, on_error=printed.append)
    try:
        deadline = time.monotonic() + 120
        while not state.problem and time.monotonic() < deadline:
            time.sleep(0.1)
    finally:
        state.stop()
    assert "damaged model bundle" in state.problem and "\n" not in state.problem, state.problem
    assert printed and all("Traceback" not in p and "\n" not in p for p in printed), printed
