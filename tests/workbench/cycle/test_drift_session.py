"""Where the model does not know, in a session: a walk from a shifted robot scores as drifted and its training walks
do not, `combined` offers it first with that reason, `classify` writes the score and warns, the Data tab shows it."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import labeling
from sessions import IngestOptions
from tests.conftest import new_session
from workbench import cycle
from workbench.demo import RunConditions, generate_demo_logs, generate_walk, seed_labels, write_walk
from workbench.export import classify_files, export_all
from workbench.ui.panel_data import logs_table_html

from .test_cycle import TINY

# a robot unlike the demo's: over twice the speed, the IMU tilted by 34 and 23 degrees and its gains far off, feet
# that read a fifth of the force
SHIFTED = RunConditions(
    speed=2.2,
    gait=1.6,
    imu_gain=(3.0, 0.3, 2.5, 3.5, 0.4, 3.0),
    force_gain=(0.2, 0.2, 0.2, 0.2),
    mount_rad=(0.6, 0.4),
)


@pytest.fixture(scope="module")
def drifted(tmp_path_factory: pytest.TempPathFactory):
    root = tmp_path_factory.mktemp("drift")
    logs = generate_demo_logs(root / "logs", n_logs=2, minutes=1.0, seed=5)
    s = new_session(root / "s")
    s.ingest(logs)
    seed_labels(s, 0.15, seed=1)
    cycle.train_predictor(s, config=TINY, hidden=8)
    cycle.train_classifier(s)
    shifted = write_walk(generate_walk(11, 60.0, conditions=SHIFTED), root / "logs" / "shifted.mcap", camera=False)
    (new,) = [x for x in s.ingest([shifted]) if x.name.startswith("shifted")]
    yield s, new, shifted
    s.close()


def test_the_shifted_walk_scores_as_drifted_and_the_training_walks_do_not(drifted) -> None:
    session, new, _ = drifted
    scores = cycle.compute_scores(session)
    share = {log_id: labeling.drifted_share(s.drift) for log_id, s in scores.scores.items()}
    trained = [x.id for x in session.logs() if x.id != new.id]
    # 15 % of two short walks labelled: much of their other time is unlike it, but far less than the new robot's
    assert all(share[i] is not None and share[i] < 0.4 for i in trained), share
    assert share[new.id] > 0.9, share
    median = {i: float(np.median(s.drift)) for i, s in scores.scores.items()}
    assert median[new.id] > 2.5 * max(median[i] for i in trained), median
    # its track is lit in the drift row, the training walks' mostly not
    assert np.mean(scores.tracks[new.id]["drift"] >= labeling.DRIFT_TRACK_AT_1) > 0.6
    # combined offers it first, and says why
    points = {x.id: cycle.signal_change_points(session, x) for x in session.logs()}
    queue = cycle.suggest_for_session(session, scores, points, logs=session.logs())
    first_log, first = queue[0]
    assert first_log.id == new.id and first.reason.startswith("unlike anything labelled")
    # the queue takes the tracks the scores carry; computing them again gives the same queue
    again = cycle.suggest_for_session(session, replace(scores, tracks={}), points, logs=session.logs())
    assert [(g.id, s.start, s.stop, s.reason, s.kind) for g, s in again] == [
        (g.id, s.start, s.stop, s.reason, s.kind) for g, s in queue
    ]
    np.testing.assert_allclose([s.score for _, s in again], [s.score for _, s in queue], rtol=1e-12)
    # the Data tab's column
    html = logs_table_html(session, share)
    assert "unlike labelled" in html and f"{share[new.id]:.0%}" in html


def test_classify_writes_the_drift_and_warns_once_for_the_shifted_file(drifted, tmp_path: Path) -> None:
    session, new, shifted = drifted
    out = tmp_path / "export"
    export_all(session, out)
    card = (out / "bundle" / "MODEL_CARD.md").read_text()
    section = card.split("## Where the model does not know", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and "%" in line]
    assert rows[0].startswith(f"| {new.name} |"), section  # the most drifted log first
    assert "scores above 1" in section
    train_file = Path(session.logs()[0].source_path)
    code, lines = classify_files(out / "bundle", [train_file, shifted], tmp_path / "p.csv", IngestOptions())
    assert code == 0, lines
    warnings = [x for x in lines if x.startswith("warning:")]
    assert len(warnings) == 1 and "shifted" in warnings[0] and "unlike anything labelled" in warnings[0], lines
    # each file's drift, its members' agreement and the agreement of its predictions within its stretches; two short
    # walks hold out too few labelled rows for a relation, so no accuracy at the drift
    said = {
        m[1]: float(m[2])
        for x in lines
        if (
            m := re.match(
                r"^(\S+): median drift ([\d.]+), \d+% of it above 1; expected accuracy \d+% by its members' "
                r"agreement, at most \d+% by its stretches",
                x,
            )
        )
    }
    assert set(said) == {train_file.stem, "shifted"} and said["shifted"] > 1 > said[train_file.stem], lines
    assert not any("at its drift" in x for x in lines), lines
    pred = pd.read_csv(tmp_path / "p.csv")
    by_log = pred.groupby("log")["drift"].apply(lambda d: float((d > 1).mean()))
    assert by_log[new.name] > 0.9 and by_log.drop(new.name).max() < 0.4


def test_classify_says_the_persons_checks_and_warns_when_the_card_is_outside_them(drifted, tmp_path: Path) -> None:
    """Issue 65, item 4: the export carries the person's checks (``checks.json``); classify says them first and warns
    when the card's estimate lies outside the spot checks' interval by 10 points or more."""
    from sessions import Session

    original, _, shifted = drifted
    with Session.open(original.copy_to(tmp_path / "copy")) as session:  # the module's other tests see no checks
        (version,) = [v for v in session.model_versions("classifier") if v.active]
        a, b = [t.name for t in session.terrains()][:2]
        log = session.logs()[0]
        for i in range(8):  # the model wrong on every spot check: the interval ends at 32 %, far under any card
            session.add_check(
                log.id, 10 * i, 10 * i + 5, a, predicted=b, agreement=0.0, classifier=version.id, kind="spot check",
                author="t",
            )  # fmt: skip
        out = tmp_path / "export"
        export_all(session, out)
    carried = json.loads((out / "bundle" / "checks.json").read_text())
    assert carried["spot"] == [0, 8] and carried["runs"] == {log.name: [0, 8]}
    code, lines = classify_files(out / "bundle", [shifted], tmp_path / "p.csv", IngestOptions())
    assert code == 0, lines
    said = "your checks in the session (at export): right on 0 of 8 spot checks (0 %, 95 % interval 0–32 %)"
    assert lines[0] == said, lines
    assert lines[1].startswith("warning: the card's estimate (") and "trust the spot checks" in lines[1], lines
    assert not any("run of this name" in x for x in lines), lines  # no run of the session is called so
    # the session's own run, classified as a file: named with the interval of the checks made in it
    code, lines = classify_files(out / "bundle", [Path(log.source_path)], tmp_path / "r.csv", IngestOptions())
    assert code == 0, lines
    assert (
        f"{log.name}: your checks in the session's run of this name found the model right on 0 of 8 checks (0 %, "
        "95 % interval 0–32 %); suggestions are placed where the model is doubted, so these run low"
    ) in lines, lines
    # a damaged file is named in one line and left out; the predictions are written all the same
    (out / "bundle" / "checks.json").write_text("[" * 50_000)
    code, lines = classify_files(out / "bundle", [shifted], tmp_path / "q.csv", IngestOptions())
    assert code == 0 and (tmp_path / "q.csv").exists(), lines
    assert lines[0].startswith("warning: ") and "checks.json: damaged" in lines[0], lines
    assert not any(x.startswith("your checks") for x in lines)
