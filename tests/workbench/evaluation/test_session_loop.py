"""``workbench evaluate loop``: the cycle on a copy of a session, judged on the logs nobody had labelled (issue 65)."""

from __future__ import annotations

import itertools
import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import labeling
from sessions import Session
from tests.conftest import new_session
from workbench.cli import main
from workbench.evaluation import LoopSettings
from workbench.evaluation.session_loop import person_labels

pytestmark = pytest.mark.usefixtures("fast_window_fits", "quick_stage1")

RATE = 50.0
TERRAINS = ("hard", "soft")


def _walk(path: Path, seed: int, *, gain: float = 1.0, seconds: float = 80.0) -> tuple[Path, list[tuple]]:
    """A 3-channel CSV whose terrain changes every 10 s: ``soft`` rings at 4 Hz, ``hard`` at 17 Hz. ``gain`` scales
    and shifts every channel: a log unlike the others, terrains as they are."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE)) / RATE
    patch = (t // 10).astype(int)
    terrain = np.array([TERRAINS[(p + seed) % 2] for p in patch])
    freq = np.where(terrain == "soft", 4.0, 17.0)
    x = np.column_stack(
        [np.sin(2 * np.pi * freq * t + k) + 0.4 * rng.normal(size=len(t)) for k in range(3)]
    ) * gain + 3.0 * (gain - 1.0)
    pd.DataFrame({"time": t, "a": x[:, 0], "b": x[:, 1], "c": x[:, 2]}).to_csv(path, index=False)
    edges = np.flatnonzero(np.diff(patch)) + 1
    bounds = [0, *edges.tolist(), len(t)]
    return path, [(path.stem, a / RATE, b / RATE, terrain[a]) for a, b in itertools.pairwise(bounds)]


@pytest.fixture(scope="module")
def loop_session(tmp_path_factory) -> tuple[Path, Path]:
    """Two labelled logs (10 % in 5 s pieces), a new log like them and a new log unlike them (gain 4); the truth of
    every log in a reference file."""
    folder = tmp_path_factory.mktemp("loop")
    made = [_walk(folder / f"w{i}.csv", i) for i in range(3)] + [_walk(folder / "odd.csv", 3, gain=4.0)]
    return walk_session(folder, made)


def walk_session(folder: Path, made: list[tuple[Path, list[tuple]]]) -> tuple[Path, Path]:
    """A session of the walks ``made`` (``_walk``'s), ``w0`` and ``w1`` labelled at 10 % in 5 s pieces, and the truth
    of every walk in a reference file: ``(session, truth)``."""
    s = new_session(folder / "s", terrains=TERRAINS)
    logs = {x.name: x for x in s.ingest([p for p, _ in made])}
    rows = [row for _, truth in made for row in truth]
    for name in ("w0", "w1"):
        for _, a, _, terrain in (r for r in rows if r[0] == name):
            s.add_segment(logs[name].id, round((a + 2) * RATE), round((a + 7) * RATE), terrain, author="seed")
    s.close()
    reference = folder / "truth.csv"
    pd.DataFrame(rows, columns=["log", "start_s", "end_s", "terrain"]).to_csv(reference, index=False)
    return folder / "s", reference


def test_the_loop_checks_the_unlike_log_first_and_leaves_the_session_as_it_was(
    loop_session: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    session, reference = loop_session
    with Session.open(session) as s:
        before = [(g.log_id, g.start, g.stop, g.terrain) for g in s.segments()]
        versions = len(s.model_versions("classifier"))
    out = tmp_path / "loop.json"
    code = main(
        [
            *("evaluate", "loop", str(session), "--reference", str(reference)),
            *("--rounds", "1", "--per-round", "6", "--strategies", "combined", "random", "--out", str(out)),
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert "the loop on 2 log(s) nobody had labelled" in text
    data = json.loads(out.read_text())
    combined, random = data["arms"]["combined"], data["arms"]["random"]
    assert [r["round"] for r in combined] == [0, 1] and combined[0]["accuracy"] == random[0]["accuracy"]
    first = combined[1]
    assert first["picks"] == 6 and first["picks_new"] >= 5  # the new logs first (one spot check may fall anywhere)
    assert re.search(r"\| combined \| 1 \| \d+ \(\d+\) \| [56] of 6 \|", text), text
    assert combined[-1]["per_log"]["odd"] > 0.5, combined[-1]  # above chance after the loop's labels
    assert combined[-1]["labelled_s"] > 0 and combined[-1]["new_s"] > 0
    # what the workbench says of each new log, beside its truth: the Data tab's figure, the checks, any warning
    said = combined[-1]["said"]
    assert set(said) == set(combined[-1]["per_log"]) and all(
        set(v) >= {"figure", "checks", "warning"} for v in said.values()
    )
    assert sum(v["checks"][1] for v in said.values()) == combined[-1]["checks"][1]
    assert "| strategy | log | accuracy (%) | the workbench's figure (%) |" in text
    assert re.search(r"combined: \d of 2 new logs pass", text), text
    with Session.open(session) as s:  # the loop worked on copies
        assert [(g.log_id, g.start, g.stop, g.terrain) for g in s.segments()] == before
        assert len(s.model_versions("classifier")) == versions and not any(s.reference(x.id) for x in s.logs())


def test_an_unknown_strategy_or_no_new_log_is_one_line(loop_session: tuple[Path, Path], capsys) -> None:
    session, _ = loop_session
    assert main(["evaluate", "loop", str(session), "--strategies", "clever"]) == 2
    assert "unknown strategy 'clever'" in capsys.readouterr().err
    assert main(["evaluate", "loop", str(session)]) == 2  # no reference in the session itself
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no log without labels has reference labels" in err[0], err


def test_the_stretch_person_labels_the_models_stretch_where_the_truth_agrees() -> None:
    truth = [np.array([0] * 10 + [1] * 30 + [0] * 10)]
    # the suggestion sits in the 1s; the model's stretch runs from 5 to 45: the person labels the 1s within it
    assert labeling.stretch_oracle((0, 20, 25), truth, (5, 45)) == [(0, 10, 40, 1)]
    assert labeling.stretch_oracle((0, 20, 25), truth, (15, 30)) == [(0, 15, 30, 1)]
    # a piece across a change: each edge grows over its own terrain, the middle as it is
    assert labeling.stretch_oracle((0, 8, 12), truth, (0, 50)) == [(0, 0, 10, 0), (0, 10, 40, 1)]
    assert labeling.oracle((0, 8, 12), truth) == [(0, 8, 10, 0), (0, 10, 12, 1)]


def test_person_labels_a_piece_or_its_stretch(loop_session: tuple[Path, Path]) -> None:
    from workbench.cycle import SessionScores

    session, _ = loop_session
    with Session.open(session) as s:
        log = s.logs()[0]
    probs = np.zeros((log.n_samples, 2), np.float32)
    probs[:, 0] = 1.0
    scores = SessionScores(1, 1, TERRAINS, {log.id: labeling.LogScores(np.zeros(log.n_samples), probs)})
    truth = {log.id: np.where(np.arange(log.n_samples) < 1000, 0, 1)}
    pick = labeling.Suggestion(0, 200, 250, 1.0, "r", 0, 0)
    assert person_labels([(log, pick)], scores, truth, person="piece") == [(log, 200, 250, 0)]
    assert person_labels([(log, pick)], scores, truth, person="stretch") == [(log, 0, 1000, 0)]
    assert LoopSettings().strategies == ("combined", "random")


def test_the_headless_loop_suggest_fill_in_import_train(
    loop_session: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """Issue 65, item 6: `workbench suggest` writes the queue as a label file; its rows filled in import as labels
    and as checks of the classifier that guessed; the rows left blank are left out; `train` closes the cycle."""
    import shutil

    session = tmp_path / "s"
    shutil.copytree(loop_session[0], session)
    out = tmp_path / "next.csv"
    assert main(["suggest", str(session), "--out", str(out)]) == 2
    assert "no model yet" in capsys.readouterr().err
    assert main(["train", str(session)]) == 0
    assert main(["suggest", str(session), "--out", str(out), "--n", "6"]) == 0
    assert "wrote 6 segment(s)" in capsys.readouterr().out
    rows = pd.read_csv(out, keep_default_na=False)
    assert list(rows.columns) == ["log", "start_s", "end_s", "terrain", "reason", "guess", "kind", "classifier"]
    assert (rows["terrain"] == "").all() and set(rows["kind"]) == {"suggestion", "spot check"}
    assert main(["suggest", str(session), "--out", str(out)]) == 2  # never over a file
    truth = pd.read_csv(loop_session[1])
    for i in range(4):  # the person labels four of the six from the truth, leaves two
        mid = (rows.loc[i, "start_s"] + rows.loc[i, "end_s"]) / 2
        hit = truth[(truth["log"] == rows.loc[i, "log"]) & (truth["start_s"] <= mid) & (mid < truth["end_s"])]
        rows.loc[i, "terrain"] = hit["terrain"].iloc[0]
    rows.to_csv(out, index=False)
    capsys.readouterr()
    assert main(["labels", "import", str(session), str(out)]) == 0
    said = capsys.readouterr().out
    assert "imported" in said and "2 row(s) with no terrain left out" in said, said
    with Session.open(session) as s:
        checks = s.checks()
        version = s.active_model("classifier").id
    assert len(checks) == 4 and {c.classifier for c in checks} == {version}
    assert all(c.predicted == g for c, g in zip(checks, rows["guess"][:4], strict=True))
    capsys.readouterr()
    assert main(["train", str(session), "--stage", "classifier"]) == 0
    printed = capsys.readouterr().out
    assert re.search(r"your checks: right on \d of 4 checks", printed), printed  # what the person's checks say
    assert "always the most common terrain" in printed  # the baseline beside the estimate (item 5)


def test_suggest_verify_writes_the_checks_the_width_needs_and_the_session_figure_rests_on_them(
    loop_session: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """`suggest --verify`: uniform pieces of the time nobody labelled, as many as the plan says, each a spot check
    of the active version once filled in; the session's figure then rests on them, and a Retrain makes it "not
    checked since the last Retrain" again."""
    import shutil

    from workbench.cycle import compute_scores, session_figures

    session = tmp_path / "s"
    shutil.copytree(loop_session[0], session)
    assert main(["train", str(session)]) == 0
    assert "the session: not checked since this Retrain" in capsys.readouterr().out
    out = tmp_path / "verify.csv"
    assert main(["suggest", str(session), "--out", str(out), "--verify", "--width", "30"]) == 0
    said = capsys.readouterr().out
    plan = re.search(r"the session: not checked yet; (\d+) checks would bring it to ±15 points", said)
    assert plan, said
    rows = pd.read_csv(out, keep_default_na=False)
    assert len(rows) == int(plan.group(1)) and set(rows["kind"]) == {"spot check"}
    assert rows["reason"].str.startswith("verification").all()
    truth = pd.read_csv(loop_session[1])
    for i in range(len(rows)):
        mid = (rows.loc[i, "start_s"] + rows.loc[i, "end_s"]) / 2
        hit = truth[(truth["log"] == rows.loc[i, "log"]) & (truth["start_s"] <= mid) & (mid < truth["end_s"])]
        rows.loc[i, "terrain"] = hit["terrain"].iloc[0]
    rows.to_csv(out, index=False)
    assert main(["labels", "import", str(session), str(out)]) == 0
    capsys.readouterr()
    again = tmp_path / "verify2.csv"
    assert main(["suggest", str(session), "--out", str(again), "--verify", "--width", "30"]) == 0
    said = capsys.readouterr().out
    assert re.search(
        rf"the session: ≈ \d+ % \(90 % interval \d+–\d+ %, from {len(rows)} checks of this version\)", said
    )
    with Session.open(session) as s:
        figure = session_figures(s, compute_scores(s)).session
        assert figure.figure is not None and figure.figure.checks == len(rows)
    assert main(["train", str(session), "--stage", "classifier"]) == 0
    capsys.readouterr()
    with Session.open(session) as s:
        stale = session_figures(s, compute_scores(s)).session
    assert stale.figure is None and stale.words().startswith("not checked since the last Retrain (v")
    # what the Retrain changed: the answers of the version before it were kept when `suggest` scored it
    assert main(["suggest", str(session), "--out", str(tmp_path / "v3.csv"), "--verify", "--width", "30"]) == 0
    moved = re.search(
        rf"the last Retrain \(v\d+ → v\d+, {len(rows)} labels\) changed the model's answer on (\d+\.\d) % of the "
        r"time nobody labelled: the session moved by at most \1 points either way",
        capsys.readouterr().out,
    )
    assert moved and 0 <= float(moved.group(1)) <= 100
    assert main(["suggest", str(session), "--out", str(tmp_path / "x.csv"), "--verify", "--width", "0"]) == 2
    # issue 99, item 5: a count past the pieces there are is capped there and said (it ran minutes: 50 draws each)
    assert main(["suggest", str(session), "--out", str(tmp_path / "all.csv"), "--verify", "--n", "10000000"]) == 0
    said = capsys.readouterr().out
    written = len(pd.read_csv(tmp_path / "all.csv"))
    assert f"asked for 10,000,000: the time nobody labelled holds {written} more piece(s) to check" in said, said
    assert 0 < written < 2_000


def test_verification_checks_are_dealt_to_runs_by_their_unlabelled_time() -> None:
    assert labeling.proportional([100, 300, 600], 10) == [1, 3, 6]
    assert labeling.proportional([1, 1, 1], 2) in ([1, 1, 0], [1, 0, 1], [0, 1, 1])
    assert sum(labeling.proportional([7, 13, 29, 2], 24)) == 24 and labeling.proportional([0, 0], 5) == [0, 0]


def test_verify_is_for_the_loop_and_a_count(tmp_path: Path, capsys) -> None:
    assert main(["evaluate", "borealtc", str(tmp_path), "--verify", "4"]) == 2
    assert "evaluate borealtc takes no --verify (evaluate loop takes it)" in capsys.readouterr().err
    assert main(["evaluate", "loop", str(tmp_path), "--verify", "-1"]) == 2
    assert "--verify -1: a number of checks" in capsys.readouterr().err


def test_the_teacher_last_arm_teaches_the_last_rounds_fit_only(
    loop_session: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """``combined-teacher-last``: the rounds before the last are the combined arm's, the last fit alone is taught."""
    from workbench.evaluation import session_loop

    taught: list[bool] = []
    real = session_loop._fit

    def recorded(session, **kw):
        if "scores" in kw:  # a round's fit (the start's fit has no scores yet)
            taught.append(kw["teach"])
        return real(session, **kw)

    monkeypatch.setattr(session_loop, "_fit", recorded)
    session, reference = loop_session
    args = ["--rounds", "3", "--per-round", "3", "--strategies", "combined-teacher-last"]
    assert main(["evaluate", "loop", str(session), "--reference", str(reference), *args]) == 0, capsys.readouterr()
    assert taught == [False, False, True]


def test_far_runs_read_as_ingest_reads_them_are_scored_by_the_bundle_export_ships_and_never_enter_the_session(
    loop_session: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Runs kept out of the session copy entirely, read with the ingest options given (headerless CSVs: a mapping),
    scored after each round by the bundle `export` would write then (taught), as `classify` scores them, with
    ``combined-untaught`` the ablation row scored by the round's own fit; the session's reference rows and the far
    runs' are one file. One loop checks all of it (three loops did: issue 102)."""
    from workbench.evaluation import session_loop

    session, reference = loop_session
    (tmp_path / "far").mkdir()
    far = [_walk(tmp_path / "far" / f"x{i}.csv", 20 + i, gain=1.5, seconds=40.0) for i in range(2)]
    for path, _ in far:  # no header, time last
        frame = pd.read_csv(path)
        frame[["a", "b", "c", "time"]].to_csv(path, index=False, header=False)
    mapping = tmp_path / "bare.toml"
    mapping.write_text(
        '[csv]\nheader = false\ncolumns = ["a", "b", "c", "stamp"]\ntime_column = "stamp"\ntime_unit = "s"\n'
    )
    both = tmp_path / "truth.csv"
    rows = pd.read_csv(reference)
    pd.concat([rows, pd.DataFrame([r for _, t in far for r in t], columns=rows.columns)]).to_csv(both, index=False)
    args = ["evaluate", "loop", str(session), "--reference", str(both), "--rounds", "1", "--per-round", "6"]
    far_args = ["--far", *(str(p) for p, _ in far)]
    assert main([*args, "--strategies", "combined", *far_args]) == 2  # read with a header: none of the channels
    assert "x0.csv" in capsys.readouterr().err
    shipped: list[tuple[bool, bool]] = []  # per round: taught asked, and the version scored is the active one
    real = session_loop.shipped_version

    def recorded(s, *, taught=True, passes=1):
        version, which = real(s, taught=taught, passes=passes)
        shipped.append((taught, version.active))
        return version, which

    monkeypatch.setattr(session_loop, "shipped_version", recorded)
    out = tmp_path / "loop.json"
    read = ["--mapping", str(mapping), "--rate", "50", "--verify", "6", "--out", str(out)]
    code = main([*args, "--strategies", "combined", "combined-untaught", *far_args, *read])
    text = capsys.readouterr().out
    assert code == 0, text
    # rounds 0 and 1 of each arm: taught versions kept beside the active one, then the active one itself
    assert shipped == [(True, False), (True, False), (False, True), (False, True)]
    arm = json.loads(out.read_text())["arms"]["combined"]
    assert all(r["far"] is not None and set(r["far_per_log"]) == {"x0", "x1"} for r in arm)
    # six verification checks of each round's model, counted apart, never labelled and never recorded
    verified = arm[-1]["verified"]
    assert all(r["verified"]["checks"] == 6 for r in arm)  # before the first round and after each
    assert verified["low"] <= verified["accuracy"] <= verified["high"]
    assert verified["truth"] == pytest.approx(arm[-1]["accuracy"])  # the same time the loop's figure is on
    assert "| combined | 0 | 6 |" in text and "| combined | 1 | 6 |" in text and "truth (%) | covers |" in text
    per_run = verified["per_run"]  # the Data tab's figure per new log, beside its truth
    assert set(per_run) == {"w2", "odd"} and sum(r[3] for r in per_run.values()) == 6
    assert "runs' intervals cover the truth" in text
    assert arm[0]["far"][0] > 0.5, arm[0]  # the bundle reads the far runs: above chance on two terrains
    assert "the shipped model on far runs (%) (balanced; mean per run)" in text and "| combined | x0 | x1 |" not in text
    assert re.search(r"\| combined \| \d+\.\d → \d+\.\d \| \d+\.\d → \d+\.\d \| \d+\.\d → \d+\.\d \|", text), text
    mean = sum(arm[-1]["far_per_log"].values()) / 2  # the mean per run, each run once
    assert f"; {100 * mean:.1f})" in text
    with Session.open(session) as s:
        assert {x.name for x in s.logs()} == {"w0", "w1", "w2", "odd"}
    # refused in one line: a far run that is a log of the session, far runs without their truth, read options alone
    assert main([*args, "--far", str(loop_session[0].parent / "w2.csv")]) == 2
    assert "w2 is a log of the session" in capsys.readouterr().err
    assert main(["evaluate", "loop", str(session), "--far", str(far[0][0])]) == 2
    assert "no log without labels has reference labels" in capsys.readouterr().err
    assert main(["evaluate", "loop", str(session), "--reference", str(reference), "--mapping", str(mapping)]) == 2
    assert "--mapping, --rate and --allow-gaps say how the --far files are read" in capsys.readouterr().err


def test_a_session_log_copied_under_another_name_is_no_far_run(
    loop_session: tuple[Path, Path], tmp_path: Path, capsys
) -> None:
    """Issue 99, item 6: a copy of a session log's file was accepted as a far run ("96.6 %" where far runs score
    61-81): far runs are compared with the session's logs by content, not name."""
    import shutil

    session, reference = loop_session
    copy = Path(shutil.copy(session.parent / "w2.csv", tmp_path / "elsewhere.csv"))
    both = tmp_path / "truth.csv"
    rows = pd.read_csv(reference)
    extra = rows[rows["log"] == "w2"].assign(log="elsewhere")
    pd.concat([rows, extra]).to_csv(both, index=False)
    args = ["evaluate", "loop", str(session), "--reference", str(both), "--rounds", "1", "--far", str(copy)]
    assert main(args) == 2
    assert "holds the recording of the session's log w2 (the same content under another name)" in (
        capsys.readouterr().err
    )


@pytest.mark.parametrize(
    ("row", "said"),
    [
        ((0.0, 10.0, ""), "row 3: terrain is empty"),
        ((0.0, 10.0, "lava"), "row 3: unknown terrain 'lava'; the far runs' truth names terrains of the session"),
        ((float("nan"), 10.0, "hard"), "row 3: start_s and end_s must be given, in seconds from the run's start"),
        ((0.0, float("inf"), "hard"), "row 3: start_s 0 and end_s inf must be finite"),
        (("soon", 10.0, "hard"), "row 3: start_s soon and end_s 10.0 must be numbers of seconds"),
        ((1e308, 2e308, "hard"), "must be finite"),
        ((500.0, 600.0, "hard"), "row 3: starts at 500 s, after the run's end (40.0 s)"),
    ],
)
def test_a_malformed_far_truth_row_is_refused_in_one_line_naming_it(tmp_path: Path, row: tuple, said: str) -> None:
    """Issue 99, item 6: such rows scored 0 % with exit 0, or ended in an internal error."""
    from types import SimpleNamespace

    from sessions import WorkbenchError
    from workbench.evaluation import read_far_runs

    path, truth = _walk(tmp_path / "far.csv", 50, seconds=40.0)
    frame = pd.DataFrame([truth[0], ("far", *row)], columns=["log", "start_s", "end_s", "terrain"])
    frame.to_csv(tmp_path / "truth.csv", index=False)
    bundle = SimpleNamespace(rate_hz=RATE, channels=("a", "b", "c"))  # what reading a far run needs of a bundle
    with pytest.raises(WorkbenchError, match=re.escape(said)):
        read_far_runs([path], tmp_path / "truth.csv", bundle, session_logs=[], terrains_known=TERRAINS)
