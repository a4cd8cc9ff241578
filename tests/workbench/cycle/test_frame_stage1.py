"""The default family's own stage 1 in a session: the next-frame predictor trains on every log, draws the surprise
track and the suggestions' embeddings, carries the classifier; a session whose stage 1 is the LSTM keeps working;
the paper family keeps its LSTM."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sessions import IngestOptions, Session, WorkbenchError
from tests.conftest import new_session
from training import FRAME_PREDICTOR_KIND, Cancelled, FramePredictor, FramePredictorFit, Predictor, load_bundle
from workbench import cycle
from workbench.cli import main
from workbench.demo import seed_labels
from workbench.export import classify_files, export_all

from .test_cycle import TINY

QUICK = FramePredictorFit(steps=100)  # what these tests check does not need the full fit


pytestmark = pytest.mark.usefixtures("fast_window_fits")  # what the fits do, not how well


@pytest.fixture(scope="module")
def demo_logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    from workbench.demo import generate_demo_logs

    return generate_demo_logs(tmp_path_factory.mktemp("logs"), n_logs=2, minutes=1.0, seed=5)


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory, demo_logs: list[Path]) -> Session:
    s = new_session(tmp_path_factory.mktemp("frames") / "s")
    s.ingest(demo_logs)
    seed_labels(s, 0.15, seed=1)
    cycle.train_frame_predictor(s, fit=QUICK)
    cycle.train_classifier(s)
    yield s
    s.close()


def test_the_default_family_trains_its_own_stage1_and_the_classifier_over_it(session: Session) -> None:
    (p,) = session.model_versions("predictor")
    (c,) = session.model_versions("classifier")
    assert p.config["kind"] == FRAME_PREDICTOR_KIND and sorted(p.config["logs"]) == [x.id for x in session.logs()]
    assert p.metrics["train_mse"] < p.metrics["copy_last_mse"]  # it learned more than copying the last frame
    stage1 = load_bundle(session.path / p.path)
    assert isinstance(stage1.predictor, FramePredictor) and stage1.stage1_kind == FRAME_PREDICTOR_KIND
    assert stage1.family == "default" and stage1.spectral is not None
    assert c.config["predictor"] == p.id and c.config["model"] == "default"
    full = load_bundle(session.path / c.path)
    assert isinstance(full.predictor, FramePredictor) and full.spectral == stage1.spectral  # the predictor's frames
    for a, b in zip(stage1.predictor.state_dict().values(), full.predictor.state_dict().values(), strict=True):
        assert np.array_equal(a.numpy(), b.numpy())


def test_scores_draw_surprise_and_embeddings_from_the_frames(session: Session) -> None:
    scores = cycle.compute_scores(session)
    assert scores.classifier == session.active_model("classifier").id
    for log in session.logs():
        s = scores.scores[log.id]
        assert s.surprise.shape == (log.n_samples,) and s.probs.shape[0] == log.n_samples
        frame = load_bundle(session.path / session.active_model("predictor").path).spectral.frame
        assert np.all(s.surprise[: frame - 1] == 0) and s.surprise[frame:].max() > 0  # causal: none before a frame
        emb = scores.embeddings[log.id]
        assert emb.shape == (log.n_samples, 64) and emb[1000:1010].shape == (10, 64)
        # a step holds the embedding of the last frame complete at or before it: constant within a hop
        rows = emb[frame - 1 : frame + 60]
        assert np.array_equal(rows[0], rows[1]) and not np.array_equal(rows[0], rows[-1])
    assert cycle.stage1_cached(session, session.active_model("predictor"), session.logs())
    cycle.store_scores(session, scores)
    kept = cycle.stored_scores(session)  # the page's first screen, from what was kept
    assert kept is not None and kept.complete
    assert kept.scores.embeddings[session.logs()[0].id].shape == scores.embeddings[session.logs()[0].id].shape


def test_a_run_whose_labels_the_classifier_learned_keeps_its_confident_answers(session: Session) -> None:
    """A run's vote takes a step as far as the model is unsure there and, until a Retrain has learned every label of
    the run, as far as the person's checks (else the card's estimate) distrust it; once the active classifier trained
    on all of them, its confidence alone decides (its labels record: ids and newest change)."""
    from workbench.cycle.run_votes import with_run_votes

    version, bundle = cycle.active_bundle(session)
    learned = version.config["labels"]
    segments = session.segments()
    logs = [x for x in session.logs() if any(g.log_id == x.id for g in segments)]
    plain = cycle.compute_scores(session, votes=False)
    outs = cycle.stage1_outputs(session, *cycle.active_predictor(session), logs)
    scored = [plain.scores[x.id] for x in logs]

    def moved(record: dict | None) -> list[np.ndarray]:  # (T,) per log: how far the vote moved each step
        out = with_run_votes(session, logs, outs, scored, bundle.classes, estimate=0.5, learned=record)
        return [np.abs(a.probs - s.probs).sum(1) for a, s in zip(out, scored, strict=True)]

    learned_all, untrusted = moved(learned), moved(None)  # trust 1, and the estimate's 0.5 (no check made)
    for a, b in zip(learned_all, untrusted, strict=True):
        assert (a <= b + 1e-5).all() and b.max() > a.max()
    # one label of the first run not in the record (new since the fit): that run is judged as before, the rest not
    first = next(g for g in segments if g.log_id == logs[0].id)
    partly = moved({**learned, "ids": [i for i in learned["ids"] if i != first.id]})
    np.testing.assert_array_equal(partly[0], untrusted[0])
    for a, b in zip(partly[1:], learned_all[1:], strict=True):
        np.testing.assert_array_equal(a, b)


def test_export_and_classify_a_bundle_with_the_frame_predictor(session: Session, tmp_path: Path) -> None:
    out = tmp_path / "export"
    written = dict((p.name, what) for p, what in export_all(session, out))
    assert "checked with onnxruntime" in written["classifier_stream.onnx"]
    card = (out / "bundle" / "MODEL_CARD.md").read_text()
    assert "predicting each short-time frame" in card and "LSTM" not in card
    log = session.logs()[0]
    code, lines = classify_files(out / "bundle", [Path(log.source_path)], tmp_path / "p.csv", IngestOptions())
    assert code == 0, lines


def test_the_paper_family_refuses_a_frame_predictor_in_one_line(session: Session) -> None:
    with pytest.raises(WorkbenchError, match=r"--model paper` to train both stages of the paper family"):
        cycle.train_classifier(session, model="paper", config=TINY, hidden=8)


def test_a_cancelled_stage1_saves_nothing_and_the_next_run_reuses_the_frames(tmp_path: Path, demo_logs) -> None:
    s = new_session(tmp_path / "s")
    s.ingest(demo_logs)
    calls = []

    def cancel() -> bool:
        calls.append(1)
        return len(calls) > 1  # after the first log's frames

    with pytest.raises(Cancelled):
        cycle.train_frame_predictor(s, fit=QUICK, cancel=cancel)
    assert s.model_versions("predictor") == []
    assert s._read("SELECT kind, status FROM runs ORDER BY id")[-1] == ("predictor", "cancelled")
    (cache,) = (s.path / "cache").glob("frames-*")
    assert len(list(cache.glob("*.npy"))) == 1  # one log's frames done, kept whole
    seen = []
    v = cycle.train_frame_predictor(s, fit=QUICK, progress=seen.append)
    frames_phase = [p for p in seen if p.epoch == 1]
    assert len(frames_phase) == 1 and frames_phase[0].steps == 1  # only the log not done before was read
    assert v.active and 0 < seen[-1].fraction <= 1.0 and seen[-1].epoch == 2
    s.close()


def test_a_session_whose_stage1_is_the_lstm_keeps_working(tmp_path: Path, demo_logs) -> None:
    """Decision: a default-family session trained before keeps its LSTM stage 1 (its classifier reads only the
    frames); the next stage-1 training replaces it with the frame predictor."""
    s = new_session(tmp_path / "s")
    s.ingest(demo_logs)
    seed_labels(s, 0.15, seed=1)
    lstm = cycle.train_predictor(s, config=TINY, hidden=8)
    first = cycle.train_classifier(s)  # the default family over the LSTM, as sessions were trained before
    scores = cycle.compute_scores(s)
    log = s.logs()[0]
    assert scores.classifier == first.id and scores.embeddings[log.id].shape == (log.n_samples, 8 + 22)
    again = cycle.train_classifier(s, warm_epochs=1)  # a Retrain in the page: the quick phase over the same LSTM
    assert again.config["predictor"] == lstm.id
    new = cycle.train_stage1(s, frame_fit=QUICK)  # the family of the active classifier: the default
    assert new.config["kind"] == FRAME_PREDICTOR_KIND and s.active_model("predictor").id == new.id
    assert cycle.compute_scores(s).classifier is None  # trained on the LSTM's normalisation: retrained, not mixed
    assert cycle.train_classifier(s).config["predictor"] == new.id
    assert len(s.segments()) > 0  # labels never touched
    s.close()


def test_the_cli_trains_the_frame_predictor_by_default_and_the_lstm_for_the_paper(
    tmp_path: Path, demo_logs, capsys, quick_stage1
):
    s = tmp_path / "s"
    assert main(["new", str(s)]) == 0
    assert main(["ingest", str(s), str(demo_logs[0])]) == 0
    assert main(["train", str(s), "--stage", "predictor"]) == 0
    assert "predictor v1 (next spectral frame): error" in capsys.readouterr().out
    paper = ["train", str(s), "--stage", "predictor", "--model", "paper", "--hidden", "8", "--max-epochs", "1"]
    assert main(paper) == 0
    assert "predictor v2: validation MSE" in capsys.readouterr().out
    with Session.open(s) as session:
        p = session.active_model("predictor")
        assert isinstance(load_bundle(session.path / p.path).predictor, Predictor) and "kind" not in p.config
