"""``workbench evaluate session``: leave-logs-out against reference labels given as a file."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from sessions import Session
from tests.conftest import new_session
from tests.workbench.cycle.test_cycle import TINY
from workbench import cycle
from workbench.cli import main
from workbench.demo import generate_demo_logs, seed_labels

pytestmark = pytest.mark.usefixtures("fast_window_fits")  # the report, not the accuracy, is under test


@pytest.fixture(params=["default", "paper"])
def three_logs(tmp_path: Path, request) -> Path:
    """Three demo logs, 30 % labelled, both stages trained; the evaluation retrains the active family per fold."""
    logs = generate_demo_logs(tmp_path / "logs", n_logs=3, minutes=0.7, seed=7)
    s = new_session(tmp_path / "s")
    s.ingest(logs)
    seed_labels(s, 0.3, seed=2)
    cycle.train_predictor(s, config=TINY, hidden=8)
    cycle.train_classifier(s, model=request.param, config=TINY, hidden=8)
    s.close()
    return tmp_path / "s"


def test_reference_from_a_file_scores_held_out_logs(three_logs: Path, tmp_path: Path, capsys) -> None:
    with Session.open(three_logs) as s:
        labels_before = s.segments()
        rows = [
            (x.name, a, b, t)
            for x in s.logs()
            for a, b, t in s.reference(x.id)  # the demo's truth, written out as a person's reference file
        ]
        with s._write() as conn:  # start from a session without reference, as a user's own logs are
            conn.execute("DELETE FROM reference")
        n_samples = sum(b - a for _, a, b, _ in rows)
        # the first reference row becomes a terrain of one log that nobody labelled: no fold can predict it
        s.add_terrain("ice")
        first = rows[0]
        rows[0] = (*first[:3], "ice")
        s.add_terrain("unused")  # a terrain of the session in neither the reference nor the labels
    frame = pd.DataFrame(rows, columns=["log", "start_sample", "end_sample", "terrain"])
    frame.to_csv(tmp_path / "reference.csv", index=False)

    code = main(
        # two epochs of the paper family's LSTM per fold: the report, not the accuracy, is under test
        [
            *("evaluate", "session", str(three_logs), "--reference", str(tmp_path / "reference.csv")),
            *("--folds", "3", "--stage2-epochs", "2"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reference: {len(rows)} row(s)" in out and "3 logs with reference, 3 folds" in out
    with Session.open(three_logs) as s:
        family = s.active_model("classifier").config["model"]
    assert f"stage 2 of the {family} family" in out
    accuracy = float(re.search(r"\*\*Accuracy ([0-9.]+) %", out).group(1))
    assert 0.0 <= accuracy <= 100.0
    section = out.split("| terrain | recall (%) |")[1].split("Confusion")[0]
    recalls = [float(r) for r in re.findall(r"^\| \S+ \| ([0-9.]+)(?: \(|\s*\|)", section, re.M)]
    balanced = float(re.search(r"balanced ([0-9.]+) %", out).group(1))
    assert recalls and abs(balanced - sum(recalls) / len(recalls)) < 0.1, (balanced, recalls)  # the recalls' mean
    assert re.search(r"\| ice \| not measurable by held-out logs: reference in 1 log\(s\)", out), out
    header, _, *rows_after = out.split("Confusion")[1].splitlines()[2:]  # after the heading and a blank line
    confusion = [line for line in rows_after if line.startswith("| ")]
    assert "ice" in header and "unused" not in header and len(confusion) == 7  # the demo's 6 and ice
    scored, unscored = (
        int(x) for x in re.search(r"Scored (\d+) reference samples; (\d+) not measurable", out).groups()
    )
    assert scored + unscored == n_samples and unscored >= first[2] - first[1]  # ice, and any terrain of one log
    assert sum(int(v) for line in confusion for v in line.strip("|").split("|")[1:]) == scored
    with Session.open(three_logs) as s:
        assert s.segments() == labels_before  # the reference trained nothing and became no label
        assert sum(b - a for x in s.logs() for a, b, _ in s.reference(x.id)) == n_samples


def test_without_reference_it_says_what_is_missing(tmp_path: Path, capsys) -> None:
    """Said before anything else is needed: this session has no model either."""
    with new_session(tmp_path / "s") as s:
        s.ingest(generate_demo_logs(tmp_path / "logs", n_logs=2, minutes=0.3, seed=7))
        with s._write() as conn:
            conn.execute("DELETE FROM reference")
    assert main(["evaluate", "session", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "0 log(s) have reference labels" in err[0] and "--reference FILE" in err[0]
