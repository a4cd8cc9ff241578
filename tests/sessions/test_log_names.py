"""One name, one run (issue 99, item 1): a log's name names one run of the session, and a label row lands on the
run it names, by its ``source_file`` where the file gives one."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sessions import LabelError, Session
from tests.conftest import new_session


def _run(path: Path, seed: int) -> Path:
    rng = np.random.default_rng(seed)
    t = np.arange(1000) / 50.0
    path.parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"time": t, "a": rng.normal(size=len(t)), "b": rng.normal(size=len(t))}).to_csv(path, index=False)
    return path


@pytest.fixture
def two_walks(tmp_path: Path) -> tuple[Session, Path, Path]:
    """A session holding ``a/walk.csv`` and then ``b/walk.csv``: two recordings of one file name."""
    s = new_session(tmp_path / "s", terrains=("grass", "sand"))
    first, second = _run(tmp_path / "a" / "walk.csv", 1), _run(tmp_path / "b" / "walk.csv", 2)
    s.ingest([first])
    s.ingest([second])
    return s, first, second


def test_a_second_recording_of_one_name_gets_a_name_of_its_own_and_says_why(two_walks) -> None:
    s, first, second = two_walks
    logs = s.logs()
    assert [x.name for x in logs] == ["walk", "walk-2"]
    assert logs[1].info["read_as"] == "walk"
    assert logs[1].info["notes"][0] == f"named walk-2: the session has another log named walk (from {first})"
    assert s.ingest([second])[0].id == logs[1].id  # the same recording again: the copy we have, no walk-3
    assert len(s.logs()) == 2


def test_a_label_row_lands_on_the_run_its_source_file_names(two_walks, tmp_path: Path) -> None:
    s, first, second = two_walks
    rows = pd.DataFrame(
        [("walk", str(second), 1.0, 3.0, "grass"), ("walk", str(first), 1.0, 3.0, "sand")],
        columns=["log", "source_file", "start_s", "end_s", "terrain"],
    )
    rows.to_csv(tmp_path / "l.csv", index=False)
    s.import_labels(tmp_path / "l.csv", author="x")
    on = {g.log_id: g.terrain for g in s.segments()}
    first_log, second_log = s.logs()
    assert on == {first_log.id: "sand", second_log.id: "grass"}
    # the export names each run by its own name: a round trip changes nothing
    back = pd.read_csv(s.export_labels(tmp_path / "e.csv"))
    assert sorted(back["log"]) == ["walk", "walk-2"]
    assert s.import_labels(tmp_path / "e.csv", author="x").already == 2


def test_a_row_whose_name_and_source_file_disagree_is_refused_and_nothing_is_imported(two_walks, tmp_path) -> None:
    s, first, _ = two_walks
    pd.DataFrame(
        [("walk", str(first), 1.0, 3.0, "grass"), ("walk-2", str(first), 5.0, 6.0, "grass")],
        columns=["log", "source_file", "start_s", "end_s", "terrain"],
    ).to_csv(tmp_path / "l.csv", index=False)
    with pytest.raises(LabelError, match=r"row 3: log 'walk-2' is from .*b/walk.csv, but source_file says"):
        s.import_labels(tmp_path / "l.csv", author="x")
    assert s.segments() == []


def test_a_name_two_logs_share_is_refused_without_a_source_file(two_walks, tmp_path: Path) -> None:
    """A session made before names were kept unique may hold two logs of one name: a row by name alone is refused
    (it went to the first of them), naming both files."""
    s, first, second = two_walks
    with s._write() as conn:  # as such a session's catalog is
        conn.execute("UPDATE logs SET name = 'walk' WHERE name = 'walk-2'")
    pd.DataFrame([("walk", 1.0, 3.0, "grass")], columns=["log", "start_s", "end_s", "terrain"]).to_csv(
        tmp_path / "l.csv", index=False
    )
    with pytest.raises(LabelError, match=rf"log 'walk' names 2 logs of the session \(from {first}, {second}\)"):
        s.import_labels(tmp_path / "l.csv", author="x")
    assert s.segments() == []
    pd.DataFrame(
        [("walk", str(second), 1.0, 3.0, "grass")], columns=["log", "source_file", "start_s", "end_s", "terrain"]
    ).to_csv(tmp_path / "l2.csv", index=False)
    s.import_labels(tmp_path / "l2.csv", author="x")  # its source_file tells which
    assert [g.log_id for g in s.segments()] == [s.logs()[1].id]


def test_the_same_recording_under_another_file_name_is_the_log_the_session_has(two_walks, tmp_path: Path) -> None:
    """A copy (or a link) of a log's file is that recording again: not a second log of the same samples."""
    import shutil

    s, first, _ = two_walks
    copy = Path(shutil.copy(first, tmp_path / "copy.csv"))
    (got,) = s.ingest([copy])
    assert got.id == s.logs()[0].id and len(s.logs()) == 2


def test_a_file_holding_a_session_logs_recording_is_found_by_its_content(two_walks, tmp_path: Path) -> None:
    import shutil

    s, first, _ = two_walks
    copy = Path(shutil.copy(first, tmp_path / "renamed.csv"))
    fresh = _run(tmp_path / "c" / "new.csv", 9)
    found = s.logs_recorded_in([copy, fresh])
    assert {p: [x.name for x in logs] for p, logs in found.items()} == {copy: ["walk"]}
