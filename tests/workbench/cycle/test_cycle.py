"""The cycle on a small session: train both stages, cache stage 1, score, export, classify, label files."""

from __future__ import annotations

import importlib
import json
import os
import re
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

import training
from sessions import LabelError, Session, WorkbenchError
from tests.conftest import TEST_TERRAINS, new_session
from training import TrainConfig, load_bundle
from workbench import cycle
from workbench.cli import main
from workbench.cycle import score_session, stage_inputs
from workbench.demo import seed_labels

TINY = TrainConfig(max_epochs=2, patience=1, chunk=32, piece=256, batch_size=16, label_piece=64, context=32, k_folds=3)


@pytest.fixture(scope="module")
def demo_logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    from workbench.demo import generate_demo_logs

    return generate_demo_logs(tmp_path_factory.mktemp("logs"), n_logs=2, minutes=1.0, seed=5)


def build_trained(path: Path, logs: list[Path], *, classifier: bool = True, model: str = "paper") -> Session:
    """A session at ``path`` with ``logs``, 15 % seed labels and tiny trained models (the classifier optional).

    The paper family by default: these tests are about its LSTM's warm starts, pieces and refits; retrains follow
    the active classifier's family. ``tests/workbench/test_default_family.py`` covers the default family."""
    s = new_session(path)
    s.ingest(logs)
    seed_labels(s, 0.15, seed=1)
    cycle.train_predictor(s, config=TINY, hidden=8)
    if classifier:
        cycle.train_classifier(s, model=model, config=TINY, hidden=8)
    return s


@pytest.fixture(scope="module")
def trained_once(tmp_path_factory: pytest.TempPathFactory, demo_logs: list[Path]) -> Path:
    """One trained session for the module; each test gets its own copy (a copy is ~20x quicker than training)."""
    path = tmp_path_factory.mktemp("trained") / "s"
    build_trained(path, demo_logs).close()
    return path


@pytest.fixture
def trained(tmp_path: Path, trained_once: Path) -> Session:
    shutil.copytree(trained_once, tmp_path / "s")
    s = Session.open(tmp_path / "s")
    yield s
    s.close()


def test_versions_are_registered_active_and_loadable(trained: Session) -> None:
    (p,) = trained.model_versions("predictor")
    (c,) = trained.model_versions("classifier")
    assert p.active and c.active and c.config["predictor"] == p.id
    bundle = load_bundle(trained.path / c.path)
    labelled = {seg.terrain for seg in trained.segments()}
    assert len(bundle.classifiers) == 3 and bundle.classes == tuple(
        t.name for t in trained.terrains() if t.name in labelled
    )
    assert bundle.channels == trained.logs()[0].channel_names
    m = c.metrics
    assert {"accuracy", "macro_f1", "per_class_recall", "confusion", "labelled_fraction"} <= set(m)
    assert 0.1 < m["labelled_fraction"] < 0.25
    runs = trained._read("SELECT kind, status FROM runs ORDER BY id")
    assert runs == [("predictor", "done"), ("classifier", "done")]


def test_a_retrain_reuses_cached_stage1_and_warm_starts(trained: Session, monkeypatch) -> None:
    calls = []
    real = stage_inputs.predictor_pass
    monkeypatch.setattr(stage_inputs, "predictor_pass", lambda *a, **k: calls.append(1) or real(*a, **k))
    v2 = cycle.train_classifier(trained, config=TINY, hidden=8)
    assert calls == []  # stage 1 was not run again: its outputs came from the cache
    assert v2.config["warm_start"] is True
    assert [v.active for v in trained.model_versions("classifier")] == [False, True]
    trained.activate_model(trained.model_versions("classifier")[0].id)  # any version can be made active again
    assert trained.active_model("classifier").id != v2.id


def test_a_warm_retrain_is_a_short_fine_tune_and_a_cold_one_is_not(trained: Session) -> None:
    long = TrainConfig(**{**TINY.__dict__, "max_epochs": 6, "patience": 6})
    warm = cycle.train_classifier(trained, config=long, hidden=8, warm_epochs=1)
    bundle = load_bundle(trained.path / warm.path)
    assert warm.config["warm_start"] is True and all(len(h) == 1 for h in bundle.info["history"])
    cold = cycle.train_classifier(trained, config=long, hidden=8, warm_start=False, warm_epochs=1)
    bundle = load_bundle(trained.path / cold.path)
    assert cold.config["warm_start"] is False and all(len(h) == 6 for h in bundle.info["history"])


def test_scores_have_the_documented_shapes(trained: Session) -> None:
    scores = score_session(trained)
    log = trained.logs()[0]
    sc = scores[log.id]
    # the per-channel error stays in the stage-1 cache; the scores carry its mean over channels
    c_version, bundle = cycle.active_bundle(trained)
    p_version = next(v for v in trained.model_versions("predictor") if v.id == c_version.config["predictor"])
    error = stage_inputs.stage1_outputs(trained, p_version, bundle, [log])[log.id].error[:]
    assert error.shape == (log.n_samples, 22) and sc.surprise.shape == (log.n_samples,)
    np.testing.assert_allclose(sc.surprise, np.square(error).mean(axis=1), rtol=1e-5)
    k = len({seg.terrain for seg in trained.segments()})  # the classes are the terrains labelled
    assert sc.probs.shape == (log.n_samples, k)
    np.testing.assert_allclose(sc.probs.sum(1), 1.0, atol=1e-5)
    assert (sc.entropy >= 0).all() and (sc.entropy <= np.log(k) + 1e-5).all()
    assert (sc.disagreement >= 0).all() and (sc.disagreement <= sc.entropy + 1e-6).all()


def test_classifier_needs_two_terrains(tmp_path: Path, demo_logs: list[Path]) -> None:
    s = new_session(tmp_path / "s")
    s.ingest(demo_logs[:1])
    with pytest.raises(WorkbenchError, match="no predictor yet"):
        cycle.train_classifier(s, config=TINY, hidden=8)
    cycle.train_predictor(s, config=TINY, hidden=8)
    s.add_segment(s.logs()[0].id, 0, 100, "grass", author="a")
    with pytest.raises(WorkbenchError, match="at least two terrains"):
        cycle.train_classifier(s, config=TINY, hidden=8)


def test_export_writes_bundle_card_checked_onnx_and_label_files(trained: Session, tmp_path: Path) -> None:
    from workbench.export import export_all

    out = tmp_path / "export"
    written = dict((p.name, what) for p, what in export_all(trained, out, predictions=True))
    assert "checked with onnxruntime" in written["classifier_stream.onnx"]
    assert set(written) >= {"bundle", "labels.csv", "labels.parquet", "labels.json", "predictions.parquet"}
    card = (out / "bundle" / "MODEL_CARD.md").read_text()
    assert "Out-of-fold metrics" in card and "imu/angular_velocity.x" in card
    # the demo walks carry a GNSS fix: where each terrain was, drawn and shown on the card
    assert (out / "bundle" / "terrain-map.png").read_bytes()[:4] == b"\x89PNG" and "terrain-map.png" in written
    assert "## Where each terrain was" in card and "of the logs have positions (gnss)" not in card
    assert re.search(r"\d+ of \d+ logs have positions \(gnss\); of the [\d,]+ poses drawn, \d+% labelled", card)
    frames = [
        pd.read_csv(out / "labels.csv"),
        pd.read_parquet(out / "labels.parquet"),
        pd.DataFrame(json.loads((out / "labels.json").read_text())),
    ]
    for f in frames:
        assert len(f) == len(trained.segments())
        assert list(f.columns[:7]) == [
            "log",
            "source_file",
            "start_s",
            "end_s",
            "start_sample",
            "end_sample",
            "terrain",
        ]
    pred = pd.read_parquet(out / "predictions.parquet")
    assert len(pred) == sum(x.n_samples for x in trained.logs())
    with pytest.raises(WorkbenchError, match="exists already"):
        export_all(trained, out)


def test_export_scores_a_group_of_logs_at_a_time_and_writes_what_one_scoring_of_every_log_gives(
    trained: Session, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Issue 66: `export --predictions` held every log's scores and a table of every step at once (a fleet's hours:
    gigabytes); it now scores a group of logs at a time and writes each log as it comes, with the same result."""
    from workbench.export import export_all, prediction_frame, predictions_stream

    whole = tmp_path / "whole"
    export_all(trained, whole, predictions=True, mcap=True)
    asked: list[list[int]] = []
    real = cycle.score_session
    monkeypatch.setattr(cycle, "score_session", lambda s, ids=None, **kw: asked.append(list(ids)) or real(s, ids, **kw))
    monkeypatch.setattr(predictions_stream, "GROUP_STEPS", 1)  # every log a group of its own
    out = tmp_path / "grouped"
    export_all(trained, out, predictions=True, mcap=True)
    logs = trained.logs()
    assert asked == [[x.id] for x in logs]
    shipped = cycle.shipped_version(trained)[0]  # the version both exports shipped (fitted once, then kept)
    bundle = load_bundle(trained.path / shipped.path)
    one_call = real(trained, version=shipped)  # what the export wrote before: every log scored at once, one table
    expected = pd.concat(
        [prediction_frame(x.name, one_call[x.id].probs, bundle.classes, x.rate_hz, one_call[x.id].drift) for x in logs],
        ignore_index=True,
    )
    for folder in (whole, out):
        pd.testing.assert_frame_equal(pd.read_parquet(folder / "predictions.parquet"), expected, rtol=1e-6)
        assert len(list((folder / "mcap").glob("*.mcap"))) == len(logs)
    assert (out / "bundle" / "MODEL_CARD.md").read_text() == (whole / "bundle" / "MODEL_CARD.md").read_text()


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="a process per core needs two cores")
def test_export_of_hours_scores_in_processes_and_writes_what_one_process_writes(
    trained: Session, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from workbench.cycle import forked_scores
    from workbench.export import export_all, predictions_stream, session_export

    here = tmp_path / "here"
    export_all(trained, here, predictions=True, mcap=True)
    pids = tmp_path / "pids"
    pids.mkdir()
    real = cycle.score_session

    def recorded(s, ids=None, **kw):
        (pids / str(os.getpid())).touch()
        return real(s, ids, **kw)

    monkeypatch.setattr(cycle, "score_session", recorded)
    monkeypatch.setattr(forked_scores, "FORK_STEPS", 1)  # the test's minutes of logs scored as hours are
    monkeypatch.setattr(predictions_stream, "GROUP_STEPS", 1)  # a log per group: several batches
    monkeypatch.setattr(session_export, "EXPORT_MIN_CORES", 2)  # as on a machine of more cores
    out = tmp_path / "forked"
    export_all(trained, out, predictions=True, mcap=True)
    assert {int(p.name) for p in pids.iterdir()} - {os.getpid()}, "the logs were scored in forked processes"
    pd.testing.assert_frame_equal(
        pd.read_parquet(out / "predictions.parquet"), pd.read_parquet(here / "predictions.parquet"), rtol=1e-6
    )
    assert len(list((out / "mcap").glob("*.mcap"))) == len(trained.logs())
    assert (out / "bundle" / "MODEL_CARD.md").read_text() == (here / "bundle" / "MODEL_CARD.md").read_text()
    assert not (out / ".scoring").exists()


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".json"])
def test_label_files_round_trip(trained: Session, tmp_path: Path, demo_logs: list[Path], suffix: str) -> None:
    path = trained.export_labels(tmp_path / f"labels{suffix}")
    other = new_session(tmp_path / "other")
    other.ingest(demo_logs)
    imported = other.import_labels(path, author="x").segments
    key = [(s.start, s.stop, s.terrain, s.author) for s in trained.segments()]
    assert [(s.start, s.stop, s.terrain, s.author) for s in other.segments()] == key
    assert len(imported) == len(key) and all(s.source == "import" for s in imported)


def test_label_import_is_all_or_nothing(trained: Session, tmp_path: Path, demo_logs: list[Path]) -> None:
    frame = pd.read_csv(trained.export_labels(tmp_path / "l.csv"))
    frame.loc[len(frame) - 1, "terrain"] = "lava"
    frame.to_csv(tmp_path / "bad.csv", index=False)
    other = new_session(tmp_path / "other")
    other.ingest(demo_logs)
    with pytest.raises(LabelError, match=rf"row {len(frame) + 1}: unknown terrain 'lava'; nothing was imported"):
        other.import_labels(tmp_path / "bad.csv", author="x")
    assert other.segments() == [] and other.history() == []
    with pytest.raises(LabelError, match="unknown log 'walk_000'"):
        new_session(tmp_path / "empty").import_labels(tmp_path / "l.csv", author="x")


def test_cli_train_export_classify_labels(tmp_path: Path, demo_logs: list[Path], capsys) -> None:
    s = tmp_path / "s"
    assert main(["new", str(s), "--terrains", *TEST_TERRAINS]) == 0
    assert main(["ingest", str(s), *map(str, demo_logs)]) == 0
    assert main(["train", str(s), "--model", "paper", "--hidden", "8", "--max-epochs", "1"]) == 0
    assert "classifier: skipped" in capsys.readouterr().out  # the paper's LSTM: both families' classifiers read it
    with Session.open(s) as session:
        seed_labels(session, 0.1, seed=2)
    assert main(["train", str(s), "--stage", "classifier", "--hidden", "8", "--max-epochs", "1"]) == 0
    out = capsys.readouterr().out
    assert "classifier v2 (default family): " in out and "measured by" in out  # the estimate per terrain
    paper = ["train", str(s), "--stage", "classifier", "--model", "paper", "--hidden", "8", "--max-epochs", "1"]
    assert main(paper) == 0
    assert "(paper family)" in capsys.readouterr().out
    assert main(["export", str(s), "--out", str(tmp_path / "x")]) == 0
    assert main(["classify", str(tmp_path / "x" / "bundle"), str(demo_logs[0]), "--out", str(tmp_path / "p.csv")]) == 0
    pred = pd.read_csv(tmp_path / "p.csv")
    assert set(pred["terrain"]) <= {"concrete", "grass", "gravel", "mulch", "dirt", "sand"}
    assert main(["labels", "export", str(s), "--out", str(tmp_path / "l.json")]) == 0
    assert main(["labels", "import", str(tmp_path / "s"), str(tmp_path / "l.json")]) == 0  # merges into itself
    assert main(["train", str(s), "--device", "cuda"]) == 2 or __import__("torch").cuda.is_available()


def test_terrain_mcap_lies_on_the_source_logs_clock(trained: Session, tmp_path: Path, demo_logs: list[Path], capsys):
    from mcap.reader import make_reader

    from tests.sessions.test_terrain_mcap import read_mcap

    def first_times(path: Path) -> dict[str, int]:
        first: dict[str, int] = {}
        with open(path, "rb") as f:
            for _, channel, m in make_reader(f).iter_messages():
                first.setdefault(channel.topic, m.log_time)
        return first

    assert main(["export", str(trained.path), "--out", str(tmp_path / "x"), "--mcap", "--frames"]) == 0
    logs = trained.logs()
    # --frames: the camera frames inside labelled segments, a folder per terrain, the very JPEGs the session keeps
    index = pd.read_csv(tmp_path / "x" / "frames" / "index.csv")
    by_log = {log.name: log for log in logs}
    expected = 0
    for seg in trained.segments():
        log = trained.log(seg.log_id)
        expected += len(trained.camera_frames_between(log.id, seg.start / 100.0, seg.stop / 100.0))
    assert len(index) == expected > 0
    for row in index.itertuples():
        log = by_log[row.log]
        seg = next(s for s in trained.segments(log.id) if s.start <= row.t_s * 100 < s.stop)
        assert row.terrain == seg.terrain and row.file.startswith(f"{seg.terrain}/{row.log}-cam0-")
        assert row.time == pytest.approx(log.t0 + row.t_s)
        kept = trained.camera_frame(log.id, row.t_s, within_s=1e-6)
        assert (tmp_path / "x" / "frames" / row.file).read_bytes() == kept.jpeg
    for log, source in zip(logs, demo_logs, strict=True):
        topics = read_mcap(tmp_path / "x" / "mcap" / f"terrain.{log.name}.mcap")
        times = np.array([t for t, _, _ in topics["/terrain"]])
        # The log's time base starts when its last sensor starts (here the feet, 3 ms after the IMU; the demo's
        # stamps are its log times) and steps at the fastest one's rate: 100 Hz, the IMU's.
        start = max(t for topic, t in first_times(source).items() if not topic.startswith("/camera"))
        assert len(times) == log.n_samples and abs(times[0] - start) <= 1_000  # float64 seconds: 0.24 µs
        assert set(np.diff(times)) == {10_000_000}
        labelled = [m for _, m, _ in topics["/terrain/labels"] if m["terrain"]]
        mine = trained.segments(log.id)
        assert [(m["terrain"], m["start_s"]) for m in labelled] == [(s.terrain, s.start / 100.0) for s in mine]

    bundle, out = str(tmp_path / "x" / "bundle"), tmp_path / "run.terrain.mcap"
    assert main(["classify", bundle, str(demo_logs[0]), "--out", str(out)]) == 0
    topics = "/terrain, /terrain/path, /terrain/geojson, /terrain/fix"  # the demo walks carry a GNSS fix
    said = f"wrote {out}: {logs[0].name}, topics {topics}, {logs[0].n_samples} messages, 2023-11-19 22:13:20.002 to "
    assert said in capsys.readouterr().out  # the demo's first walk starts at 1.7e9 s, plus its feet's 3 ms
    by_classify = [t for t, _, _ in read_mcap(out)["/terrain"]]
    by_export = [t for t, _, _ in read_mcap(tmp_path / "x" / "mcap" / f"terrain.{logs[0].name}.mcap")["/terrain"]]
    assert by_classify == by_export

    assert main(["classify", bundle, str(demo_logs[0]), "--out", str(tmp_path / "p.txt")]) == 2
    assert "unknown output type '.txt'; use .csv, .parquet, .json, .mcap" in capsys.readouterr().err
    source = demo_logs[0].read_bytes()
    for target in (out, demo_logs[0]):  # its own output again, and the robot's log itself: both refused, unchanged
        assert main(["classify", bundle, str(demo_logs[0]), "--out", str(target)]) == 2
        err = capsys.readouterr().err.strip()
        assert err == f"error: {target}: exists already (a file); the workbench writes a new file, choose a new name"
    assert demo_logs[0].read_bytes() == source

    assert main(["labels", "export", str(trained.path), "--out", str(tmp_path / "labels.mcap")]) == 0
    assert (
        f"topics /terrain/labels, {topics.partition(', ')[2]}, {len(trained.segments(logs[0].id))} segment(s)"
        in capsys.readouterr().out
    )
    written = sorted(p.name for p in tmp_path.glob("labels*.mcap"))
    assert written == [f"labels.{log.name}.mcap" for log in logs]  # one file a log: each its own timeline
    assert main(["labels", "export", str(trained.path), "--out", str(tmp_path / "labels.mcap")]) == 2
    assert "exists already" in capsys.readouterr().err


def test_cli_evaluate_qcat_on_a_generated_fixture(tmp_path: Path, capsys) -> None:
    from tests.sessions.test_ingest_csv import qcat_fixture

    for terrain in range(6):
        qcat_fixture(tmp_path, terrain=str(terrain), speed=1, trials=4, rows=80)
    code = main(
        [
            "evaluate",
            "qcat",
            str(tmp_path),
            "--hidden",
            "8",
            "--folds",
            "2",
            "--stage1-epochs",
            "2",
            "--stage2-epochs",
            "3",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "24 trials, 192 step sequences" in out
    assert "paper's split" in out and "trials held out" in out and "| paper: proposed method (published) | 89.04" in out


def test_a_warm_retrain_learns_the_new_and_changed_labels_and_keeps_folds_with_nothing_new(trained: Session) -> None:
    first = trained.active_model("classifier")
    assert sorted(first.config["labels"]["ids"]) == sorted(s.id for s in trained.segments())
    same = cycle.train_classifier(trained, config=TINY, hidden=8, warm_epochs=1)
    assert same.config["new_labels"] == 0  # nothing new: every fold keeps its model
    before, after = (load_bundle(trained.path / v.path).classifiers for v in (first, same))
    for a, b in zip(before, after, strict=True):
        for (name, x), y in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
            assert torch.equal(x, y), name

    segs = trained.segments()
    count = {t: sum(x.terrain == t for x in segs) for t in {x.terrain for x in segs}}
    seg = next(x for x in segs if count[x.terrain] >= 2)  # relabelling it keeps every class labelled
    other = next(t for t in count if t != seg.terrain)  # a labelled terrain: the classes stay, so a warm start
    trained.change_segment(seg.id, author="test", terrain=other)  # a changed label counts as new
    log = trained.logs()[0]
    taken = [(s.start, s.stop) for s in trained.segments(log.id)]
    start = next(a for a in range(0, log.n_samples - 200, 50) if all(a + 100 <= s or a >= e for s, e in taken))
    trained.add_segment(log.id, start, start + 100, segs[1].terrain, author="test")
    fresh = cycle.train_classifier(trained, config=TINY, hidden=8, warm_epochs=1)
    assert fresh.config["new_labels"] == 2 and fresh.config["warm_start"] is True
    cold = cycle.train_classifier(trained, config=TINY, hidden=8, warm_start=False)
    assert cold.config["new_labels"] is None  # a full run trains on every label


def test_a_retrain_pairs_unlabelled_neighbours_within_the_logs_change_points(trained: Session, monkeypatch) -> None:
    seen = {}
    paper = training.family("paper")

    def spy(*args, **kwargs):
        seen["pairs"] = kwargs["pairs"]
        return paper.fit(*args, **kwargs)

    # the family's fit, as the registry hands it to the cycle
    monkeypatch.setattr(importlib.import_module("training.paper_lstm"), "FAMILY", replace(paper, fit=spy))
    cycle.train_classifier(trained, config=replace(TINY, consistency=3.0), hidden=8)
    logs = cycle.model_logs(trained)
    assert seen["pairs"], "the demo logs hold neighbour pairs"
    for a, b in seen["pairs"]:
        log = logs[a.seq]
        cps = stage_inputs.log_change_points(trained.array(log.id), None, rate_hz=log.rate_hz)
        assert a.length == b.length == TINY.context + TINY.label_piece and b.start - a.start == TINY.label_piece
        assert b.stop <= log.n_samples and not ((a.stop - 1 < cps) & (cps <= b.stop - 1)).any()
    cycle.train_classifier(trained, config=TINY, hidden=8)
    assert TINY.consistency == 0.0 and seen["pairs"] == []  # the default, labels alone: no pairs built
