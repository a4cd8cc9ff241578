"""An export's staging folder: a killed export's is swept by the next export into the same folder, a live one's is
left alone, and a target that could never be renamed to is refused before any work (issue 64, item 4)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sessions import WorkbenchError
from tests.conftest import REPO
from workbench.export.export_staging import LOCK_FILE, check_target, staged, staging_folder, sweep_dead_exports

HOLD = """
import importlib.util, sys, time
from pathlib import Path
# the module alone, not the export room (which loads torch): the child is up in a fraction of a second
spec = importlib.util.spec_from_file_location("workbench.export.export_staging", "workbench/export/export_staging.py")
staging = importlib.util.module_from_spec(spec)
spec.loader.exec_module(staging)
with staging.staged(Path(sys.argv[1])) as tmp:
    (tmp / "bundle").mkdir()
    print("writing", flush=True)
    time.sleep(600)
"""


def _exporting(out: Path) -> subprocess.Popen:
    """A child in the middle of an export to ``out``, as ``kill -9`` would find it."""
    child = subprocess.Popen([sys.executable, "-c", HOLD, str(out)], cwd=REPO, stdout=subprocess.PIPE, text=True)
    assert child.stdout is not None and child.stdout.readline().strip() == "writing"
    return child


def test_a_killed_exports_folder_is_swept_by_the_next_export_beside_it(tmp_path: Path) -> None:
    """Before: ``.X.partial/`` stayed until the next export to that very name."""
    killed, live = _exporting(tmp_path / "killed"), _exporting(tmp_path / "live")
    try:
        killed.send_signal(signal.SIGKILL)
        killed.wait()
        assert staging_folder(tmp_path / "killed").is_dir()
        with staged(tmp_path / "another") as tmp:
            (tmp / "model.json").write_text("{}")
        assert not staging_folder(tmp_path / "killed").exists()  # swept
        assert (staging_folder(tmp_path / "live") / "bundle").is_dir()  # its export lives: left alone
        assert sorted(p.name for p in (tmp_path / "another").iterdir()) == ["model.json"]  # no lock file left
        with pytest.raises(WorkbenchError, match="another export to it is running"), staged(tmp_path / "live"):
            pass
    finally:
        live.kill()
        live.wait()
    assert sweep_dead_exports(tmp_path) == [staging_folder(tmp_path / "live")]


def test_a_folder_of_someone_elses_named_partial_is_never_swept(tmp_path: Path) -> None:
    theirs = tmp_path / ".notes.partial"
    theirs.mkdir()
    (theirs / "draft.txt").write_text("mine")
    old = time.time() - 3600
    os.utime(theirs, (old, old))
    empty = tmp_path / ".old-export.partial"  # an export killed before its lock existed, an hour ago
    empty.mkdir()
    os.utime(empty, (old, old))
    young = tmp_path / ".starting.partial"  # an export between its mkdir and its lock
    young.mkdir()
    assert sweep_dead_exports(tmp_path) == [empty]
    assert (theirs / "draft.txt").exists() and young.exists() and not (young / LOCK_FILE).exists()


def test_a_target_that_cannot_be_renamed_to_is_refused_first(tmp_path: Path) -> None:
    """Before: ``export --out`` a dangling symbolic link failed with NotADirectoryError after the whole export."""
    dangling = tmp_path / "link"
    dangling.symlink_to(tmp_path / "gone")
    with pytest.raises(WorkbenchError, match="exists already \\(a symbolic link to nothing\\)"):
        check_target(dangling)
    (tmp_path / "file").write_text("x")
    with pytest.raises(WorkbenchError, match="is not a folder"):
        check_target(tmp_path / "file" / "out")
    with pytest.raises(ValueError), staged(tmp_path / "fails") as tmp:
        (tmp / "half").write_text("x")
        raise ValueError("an export that fails")
    assert not (tmp_path / "fails").exists() and not staging_folder(tmp_path / "fails").exists()
