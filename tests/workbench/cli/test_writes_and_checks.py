"""Writes only where asked, checks counted once (issue 81): every writer's target is checked in one place before any
work and written new; a piece checks a classifier version once; a renamed terrain is the same terrain; a suggestion
file's check fields are what the session has; ``evaluate loop`` leaves no copy behind."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sessions import Session, WorkbenchError, new_file, write_frame
from tests.conftest import REPO, new_session
from tests.workbench.evaluation.test_session_loop import _walk, walk_session
from workbench.cli import main
from workbench.scratch_folders import LOCK_FILE, scratch_folder, sweep_scratch

pytestmark = pytest.mark.usefixtures("fast_window_fits")


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> tuple[Path, Path]:
    """A trained session of three walks (two labelled at 10 %, one new) and the truth of every walk."""
    from functools import partial

    from workbench.cycle import frame_stage1

    folder = tmp_path_factory.mktemp("trained")
    session, truth = walk_session(folder, [_walk(folder / f"w{i}.csv", i, seconds=60.0) for i in range(3)])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(frame_stage1, "FramePredictorFit", partial(frame_stage1.FramePredictorFit, steps=60))
        assert main(["train", str(session)]) == 0
    return session, truth


def _copy(trained: tuple[Path, Path], tmp_path: Path) -> Path:
    shutil.copytree(trained[0], tmp_path / "s")
    return tmp_path / "s"


def _filled(suggested: Path, truth: Path, out: Path, *, rename: dict[str, str] | None = None) -> pd.DataFrame:
    """The suggestion file with every terrain filled in from the truth, as a careful person would."""
    rows = pd.read_csv(suggested, keep_default_na=False, dtype={"classifier": str})
    known = pd.read_csv(truth)
    for i in range(len(rows)):
        mid = (rows.loc[i, "start_s"] + rows.loc[i, "end_s"]) / 2
        hit = known[(known["log"] == rows.loc[i, "log"]) & (known["start_s"] <= mid) & (mid < known["end_s"])]
        rows.loc[i, "terrain"] = (rename or {}).get(hit["terrain"].iloc[0], hit["terrain"].iloc[0])
    rows.to_csv(out, index=False)
    return rows


def _one_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


# ------------------------------------------------------------------------------------------- item 1 and item 2
def test_every_writer_refuses_links_files_folders_and_missing_folders_before_any_work(
    trained: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    session = _copy(trained, tmp_path)
    outside = tmp_path / "outside"
    outside.mkdir()
    kept = tmp_path / "kept.csv"
    kept.write_text("somebody's\n")
    dangling, to_kept = tmp_path / "d.csv", tmp_path / "k.csv"
    dangling.symlink_to(outside / "x.csv")
    to_kept.symlink_to(kept)
    assert main(["export", str(session), "--out", str(tmp_path / "export")]) == 0
    bundle = tmp_path / "export" / "bundle"
    capsys.readouterr()
    log = trained[0].parent / "w2.csv"
    writers = {
        "suggest": lambda out: ["suggest", str(session), "--out", str(out)],
        "labels export": lambda out: ["labels", "export", str(session), "--out", str(out)],
        "label studio": lambda out: ["labels", "export", str(session), "--out", str(out), "--format", "label-studio"],
        "classify": lambda out: ["classify", str(bundle), str(log), "--out", str(out)],
        "evaluate loop": lambda out: ["evaluate", "loop", str(session), "--out", str(out)],
    }
    targets = {
        "a dangling link": (dangling, "a symbolic link to nothing"),
        "a link to a file": (to_kept, "a symbolic link"),
        "a file": (kept, "(a file)"),
        "a missing folder": (tmp_path / "nowhere" / "x.csv", "does not exist"),
    }
    for target, _ in list(targets.values())[:3]:  # the same targets named .json, for the writers of JSON
        if target.is_symlink():
            target.with_suffix(".json").symlink_to(os.readlink(target))
        else:
            target.with_suffix(".json").write_text("somebody's\n")
    for writer, args in writers.items():
        for what, (target, says) in targets.items():
            json_target = target.with_suffix(".json") if writer in ("label studio", "evaluate loop") else target
            assert main(args(json_target)) == 2, (writer, what)
            line = _one_error(capsys)
            assert str(json_target) in line and says in line, (writer, what, line)
    assert not (outside / "x.csv").exists() and kept.read_text() == "somebody's\n"
    assert main(["export", str(session), "--out", str(outside)]) == 2  # a folder where the export's folder would go
    assert "(a folder)" in _one_error(capsys)
    assert main(["export", str(session), "--out", str(tmp_path / "nowhere" / "e")]) == 2
    assert "does not exist" in _one_error(capsys)
    # before any work: an untrained session is told of its target before it is told it has no model
    fresh = new_session(tmp_path / "fresh")
    fresh.close()
    assert main(["suggest", str(tmp_path / "fresh"), "--out", str(dangling)]) == 2
    assert "symbolic link" in _one_error(capsys)


def test_a_file_made_while_the_output_is_written_is_left_as_it_is(tmp_path: Path) -> None:
    target = tmp_path / "next.csv"
    with pytest.raises(WorkbenchError, match="was created while the output was written"), new_file(target) as tmp:
        tmp.write_text("ours\n")
        target.write_text("theirs\n")  # someone else's, made meanwhile
    assert target.read_text() == "theirs\n"
    assert [p.name for p in tmp_path.iterdir()] == ["next.csv"]  # no temporary file left
    with pytest.raises(WorkbenchError, match="exists already"):
        write_frame(pd.DataFrame({"a": [1]}), target)
    written = write_frame(pd.DataFrame({"a": [1]}), tmp_path / "new.parquet")
    assert pd.read_parquet(written)["a"].tolist() == [1]
    assert oct(written.stat().st_mode & 0o777) == oct(0o666 & ~_umask())  # a new file as any other: the umask's


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# -------------------------------------------------------------------------------------------------- item 3
def test_a_suggestion_file_imported_twice_counts_its_checks_once(
    trained: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    session = _copy(trained, tmp_path)
    assert main(["suggest", str(session), "--out", str(tmp_path / "next.csv"), "--n", "6"]) == 0
    _filled(tmp_path / "next.csv", trained[1], tmp_path / "filled.csv")
    capsys.readouterr()
    assert main(["labels", "import", str(session), str(tmp_path / "filled.csv")]) == 0
    first = capsys.readouterr().out
    assert "6 new label(s); 6 new check(s) of the model" in first, first
    with Session.open(session) as s:
        checks, segments, history = len(s.checks()), len(s.segments()), len(s.history())
    assert checks == 6
    assert main(["labels", "import", str(session), str(tmp_path / "filled.csv")]) == 0
    again = capsys.readouterr().out
    assert "0 new label(s), 6 already labelled so" in again and "0 new check(s)" in again, again
    assert "6 checked before (counted once)" in again, again
    with Session.open(session) as s:
        assert (len(s.checks()), len(s.segments()), len(s.history())) == (checks, segments, history)
    # fifty copies of one filled row: one label, one check
    rows = pd.read_csv(tmp_path / "filled.csv", keep_default_na=False, dtype={"classifier": str})
    other = _copy(trained, tmp_path / "other")
    pd.concat([rows.iloc[[0]]] * 50).to_csv(tmp_path / "fifty.csv", index=False)
    # issue 99, item 2: a session that did not write these suggestions takes them as labels, not as checks
    unwritten = _copy(trained, tmp_path / "unwritten")
    with Session.open(unwritten) as s:
        labels_before = len(s.segments())
    assert main(["labels", "import", str(unwritten), str(tmp_path / "fifty.csv")]) == 0
    said = capsys.readouterr().out
    assert "50 row(s) the session did not write as suggestions of that model: labels, not counted" in said, said
    with Session.open(unwritten) as s:
        assert len(s.checks()) == 0 and len(s.segments()) == labels_before + 1
    assert main(["suggest", str(other), "--out", str(tmp_path / "other.csv"), "--n", "6"]) == 0  # the same queue
    capsys.readouterr()
    assert main(["labels", "import", str(other), str(tmp_path / "fifty.csv")]) == 0
    said = capsys.readouterr().out
    assert "imported 50 row(s)" in said and "1 new label(s), 49 already labelled so" in said, said
    with Session.open(other) as s:
        assert len(s.checks()) == 1


def test_a_check_is_of_the_kind_and_guess_the_session_wrote_not_the_files_columns(
    trained: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """Issue 99, item 2: a verify file filled with the truth and its terrain copied into the guess made the figure
    "≈ 100 %"; a guess naming no terrain was stored as the model's answer; a suggestion relabelled "spot check"
    counted as a uniform check. Each is refused with its row named, and nothing is imported."""
    session = _copy(trained, tmp_path)
    assert main(["suggest", str(session), "--out", str(tmp_path / "next.csv"), "--n", "6"]) == 0
    rows = _filled(tmp_path / "next.csv", trained[1], tmp_path / "filled.csv")
    capsys.readouterr()
    other = "soft" if rows.loc[0, "guess"] == "hard" else "hard"  # not what the model answered on row 2's piece
    kind = "suggestion" if rows.loc[0, "kind"] == "spot check" else "spot check"

    def first(column: str, value: str) -> pd.DataFrame:
        return rows.assign(**{column: [value, *rows[column][1:]]})

    forged = {
        "guess": first("guess", other),
        "hyperlink": first("guess", '=HYPERLINK("x")'),
        "kind": first("kind", kind),
    }
    with Session.open(session) as s:
        before = (len(s.segments()), len(s.checks()))
    for what, frame in forged.items():
        frame.to_csv(tmp_path / f"{what}.csv", index=False)
        assert main(["labels", "import", str(session), str(tmp_path / f"{what}.csv")]) == 2, what
        said = _one_error(capsys)
        if what == "kind":
            assert f"row 2: kind {kind!r} is not what the session drew for this piece" in said, said
        else:
            assert "row 2: guess" in said and "is not the answer classifier v" in said, said
        with Session.open(session) as s:
            assert (len(s.segments()), len(s.checks())) == before, what
    assert main(["labels", "import", str(session), str(tmp_path / "filled.csv")]) == 0  # the honest file
    assert "6 new check(s) of the model" in capsys.readouterr().out


def test_a_session_whose_checks_were_counted_twice_keeps_each_once_after_the_upgrade(
    trained: tuple[Path, Path], tmp_path: Path
) -> None:
    import sqlite3

    session = _copy(trained, tmp_path)
    conn = sqlite3.connect(session / "session.sqlite", isolation_level=None)
    conn.executescript(  # as released
        "DROP TABLE issued; DROP INDEX checks_once; DROP TABLE terrain_renames; PRAGMA user_version = 2"
    )
    row = (1, 0, 10, "hard", "hard", 1.0, 2, "suggestion", "me", "now")
    for _ in range(3):  # one file imported three times
        conn.execute(
            "INSERT INTO checks (log_id, start, stop, terrain, predicted, agreement, classifier, kind, author, at) "
            "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
            row,
        )
    conn.close()
    with Session.open(session) as s:
        assert len(s.checks()) == 1


# -------------------------------------------------------------------------------------------------- item 4
def test_right_guesses_stay_right_after_a_rename_in_the_file_and_on_the_page(
    trained: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    from workbench.cycle import compute_scores, record_check

    session = _copy(trained, tmp_path)
    assert main(["suggest", str(session), "--out", str(tmp_path / "next.csv"), "--n", "8"]) == 0
    assert main(["terrains", str(session), "rename", "hard", "asphalt"]) == 0
    rows = _filled(tmp_path / "next.csv", trained[1], tmp_path / "filled.csv", rename={"hard": "asphalt"})
    right = int((rows["guess"].replace({"hard": "asphalt"}) == rows["terrain"]).sum())
    assert right > 0  # the model is right somewhere: the case this test is about
    assert main(["labels", "import", str(session), str(tmp_path / "filled.csv")]) == 0
    with Session.open(session) as s:
        checks = s.checks()
        assert sum(c.agreement for c in checks) == right and sum(c.right for c in checks) == right
        assert {c.predicted for c in checks} <= {"asphalt", "soft"}
        # the page: the scores still name the classes as the classifier was trained (hard); the person says asphalt
        scores = compute_scores(s)
        assert "hard" in scores.classes
        log = next(x for x in s.logs() if x.name == "w2")
        said = scores.scores[log.id].probs.argmax(axis=1)
        where = int(np.flatnonzero(said == list(scores.classes).index("hard"))[0])
        check = record_check(s, scores, log.id, where, where + 1, "asphalt", kind="manual", author="me")
        assert check is not None and check.right and check.agreement == 1.0
    # a suggestion file written after the rename names the terrain as the session does now
    capsys.readouterr()
    assert main(["suggest", str(session), "--out", str(tmp_path / "after.csv"), "--n", "4"]) == 0
    assert set(pd.read_csv(tmp_path / "after.csv")["guess"]) <= {"asphalt", "soft"}


# -------------------------------------------------------------------------------------------------- item 5
@pytest.mark.parametrize(
    ("column", "value", "says"),
    [
        ("classifier", "999", "'999' is not a classifier version of this session (it has v2)"),
        ("classifier", "-1", "'-1' is not a classifier version"),
        ("classifier", "0", "'0' is not a classifier version"),
        ("classifier", "2.7", "'2.7' is not a classifier version"),
        ("classifier", "1", "'1' is not a classifier version"),  # the predictor's version
        ("classifier", "true", "'true' is not a classifier version"),
        ("classifier", "nan", "'nan' is not a classifier version"),
        ("classifier", "", "the guess 'soft' names no classifier version"),
        ("classifier", "inf", "'inf' is not a classifier version"),
        ("classifier", "abc", "'abc' is not a classifier version"),
        ("classifier", "1e400", "'1e400' is not a classifier version"),
        ("kind", "bogus", "kind 'bogus' is not a kind of check"),
        ("kind", "spot\x1b[31m", "the kind holds a control character"),
        ("guess", "g" * 301, "guess is 301 characters long"),
        ("guess", "soft\x07", "the guess holds a control character"),
    ],
)
def test_a_forged_check_field_refuses_the_file_naming_its_row(
    trained: tuple[Path, Path], tmp_path: Path, capsys, column: str, value: str, says: str
) -> None:
    session = _copy(trained, tmp_path)
    assert main(["suggest", str(session), "--out", str(tmp_path / "next.csv"), "--n", "3"]) == 0
    rows = _filled(tmp_path / "next.csv", trained[1], tmp_path / "filled.csv")
    rows[column] = rows[column].astype(object)
    rows.loc[1, column] = value
    rows.loc[1, "guess"] = "soft" if column != "guess" else value
    rows.to_csv(tmp_path / "forged.csv", index=False)
    capsys.readouterr()
    with Session.open(session) as s:
        before = (len(s.checks()), len(s.segments()))
    assert main(["labels", "import", str(session), str(tmp_path / "forged.csv")]) == 2
    line = _one_error(capsys)
    assert "forged.csv: row 3:" in line and says in line and "nothing was imported" in line, line
    with Session.open(session) as s:
        assert (len(s.checks()), len(s.segments())) == before


def test_a_json_true_or_a_whole_float_as_the_version(trained: tuple[Path, Path], tmp_path: Path, capsys) -> None:
    session = _copy(trained, tmp_path)
    row = {"log": "w2", "start_s": 1.0, "end_s": 2.0, "terrain": "soft", "guess": "soft", "kind": "spot check"}
    (tmp_path / "true.json").write_text(pd.DataFrame([{**row, "classifier": True}]).to_json(orient="records"))
    assert main(["labels", "import", str(session), str(tmp_path / "true.json")]) == 2
    assert "classifier 'True' is not a classifier version" in _one_error(capsys)
    (tmp_path / "float.json").write_text(pd.DataFrame([{**row, "classifier": 2.0}]).to_json(orient="records"))
    with Session.open(session) as s:  # the session wrote this piece for v2 (a check is of what it drew)
        w2 = next(x for x in s.logs() if x.name == "w2")
        s.record_issued([(w2.id, round(w2.rate_hz), round(2 * w2.rate_hz), 2, "spot check", "soft")])
    assert main(["labels", "import", str(session), str(tmp_path / "float.json")]) == 0
    with Session.open(session) as s:
        assert [(c.classifier, c.kind) for c in s.checks()] == [(2, "spot check")]


# -------------------------------------------------------------------------------------------------- item 7
def test_evaluate_loop_stopped_by_sigterm_removes_its_copy(trained: tuple[Path, Path], tmp_path: Path) -> None:
    temp = tmp_path / "temp"
    temp.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-m", "workbench.cli", "evaluate", "loop", str(trained[0]), "--reference", str(trained[1])],
        cwd=REPO,
        env={**os.environ, "TMPDIR": str(temp)},
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    deadline = time.monotonic() + 60
    while not list(temp.glob("workbench-loop-*/start")) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert list(temp.glob("workbench-loop-*/start")), "the loop made no copy"
    proc.send_signal(signal.SIGTERM)
    out = proc.communicate(timeout=60)[0].decode()
    assert proc.returncode == 143, out
    assert "Traceback" not in out
    assert not list(temp.glob("workbench-loop-*")), list(temp.iterdir())


def test_a_copy_whose_process_is_gone_is_swept_by_the_next_and_a_live_one_is_not(tmp_path: Path) -> None:
    dead = tmp_path / "workbench-loop-dead"
    dead.mkdir()
    (dead / LOCK_FILE).touch()  # its lock held by nobody: the process that took it was killed
    with scratch_folder("workbench-loop-", folder=tmp_path) as live:
        assert not dead.exists()
        assert sweep_scratch("workbench-loop-", folder=tmp_path) == [] and live.is_dir()
    assert not live.exists()


# -------------------------------------------------------------------------------------------------- item 8
def test_the_small_ones(trained: tuple[Path, Path], tmp_path: Path, capsys) -> None:
    session, truth = trained
    assert main(["evaluate", "loop", str(session), "--rounds", "0"]) == 2
    assert "--rounds 0: at least one round" in _one_error(capsys)
    assert main(["evaluate", "loop", str(session), "--strategies"]) == 2
    assert "--strategies: name at least one" in _one_error(capsys)
    assert main(["evaluate", "demo", str(session), "--out", str(tmp_path / "x.json")]) == 2
    assert "writes no file" in _one_error(capsys)
    (tmp_path / "far.csv").write_text("log,start_s,end_s,terrain\nw2,1,1e308,soft\n")
    assert main(["labels", "import", str(session), str(tmp_path / "far.csv")]) == 2
    assert "end_s is 1e+308, out of range" in _one_error(capsys)
    (tmp_path / "blank.csv").write_text("log,start_s,end_s,terrain\nw2,1,3,\n")
    args = ["labels", "import", str(session), str(tmp_path / "blank.csv"), "--reference", "--create-terrains"]
    assert main(args) == 2
    line = _one_error(capsys)
    assert "terrain is empty" in line and "--create-terrains" not in line, line
    assert main(["suggest", str(session), "--out", str(tmp_path / "many.csv"), "--n", "10000000"]) == 0
    said = capsys.readouterr().out
    assert "asked for 10,000,000: the session holds" in said, said
    # an error raised in the loop's copy names the session
    one = _copy(trained, tmp_path / "one")
    with Session.open(one) as s:
        for g in s.segments():
            if g.terrain == "soft":
                s.delete_segment(g.id, author="me")
    assert main(["evaluate", "loop", str(one), "--reference", str(truth), "--rounds", "1"]) == 2
    line = _one_error(capsys)
    assert line.startswith(f"error: {one}:") and "workbench-loop-" not in line, line
