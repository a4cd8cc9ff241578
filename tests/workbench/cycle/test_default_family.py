"""The default family in a session: trained, scored, streamed, exported and classified with the same numbers."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from sessions import Session
from tests.conftest import new_session
from training import StreamingClassifier, load_bundle
from workbench import cycle
from workbench.cycle import score_session, signal_change_points, stretch_units, unlabelled_stretches
from workbench.demo import seed_labels
from workbench.export import classify_files, export_all

from .test_cycle import TINY

pytestmark = pytest.mark.usefixtures("fast_window_fits")  # what the fits do, not how well


def trained_demo_session(root: Path, *, seed: int, label_seed: int) -> Session:
    """Two 1-minute demo walks, 15 % labelled, a tiny stage 1 and the default family's stage 2."""
    from workbench.demo import generate_demo_logs

    logs = generate_demo_logs(root / "logs", n_logs=2, minutes=1.0, seed=seed)
    s = new_session(root / "s")
    s.ingest(logs)
    seed_labels(s, 0.15, seed=label_seed)
    cycle.train_predictor(s, config=TINY, hidden=8)
    cycle.train_classifier(s)  # no family named: the default
    return s


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Session:
    s = trained_demo_session(tmp_path_factory.mktemp("default"), seed=5, label_seed=1)
    yield s
    s.close()


def test_the_first_classifier_is_the_default_family_and_retrains_keep_the_family(session: Session) -> None:
    (c,) = session.model_versions("classifier")
    assert c.config["model"] == "default" and c.config["self_training_stretches"] > 0
    bundle = load_bundle(session.path / c.path)
    assert bundle.family == "default" and bundle.spectral is not None and len(bundle.classifiers) == 5
    assert bundle.classifiers[0].config.n_features == bundle.spectral.step_width
    labelled = {seg.terrain for seg in session.segments()}
    assert set(bundle.classes) == labelled  # wall 4: a terrain nobody labelled is no class (no empty card rows)
    assert list(bundle.classes) == [t.name for t in session.terrains() if t.name in labelled]
    assert {"accuracy", "macro_f1", "confusion", "pseudo_stretches"} <= set(c.metrics)
    paper = cycle.train_classifier(session, model="paper", config=TINY, hidden=8)
    assert paper.config["model"] == "paper" and load_bundle(session.path / paper.path).family == "paper"
    again = cycle.train_classifier(session, config=TINY, hidden=8)  # a Retrain follows the active family
    assert again.config["model"] == "paper"
    back = cycle.train_classifier(session, model="default")
    assert back.config["model"] == "default" and session.active_model("classifier").id == back.id


def test_scores_stream_and_classify_agree_on_every_step(session: Session, tmp_path: Path) -> None:
    if session.active_model("classifier").config["model"] != "default":
        cycle.train_classifier(session, model="default")
    log = session.logs()[0]
    scored = score_session(session, [log.id])[log.id]
    assert scored.probs.shape == (log.n_samples, len({seg.terrain for seg in session.segments()}))
    np.testing.assert_allclose(scored.probs.sum(1), 1.0, atol=1e-5)
    _, bundle = cycle.active_bundle(session)
    streamed = StreamingClassifier(bundle).run(np.asarray(session.array(log.id)))
    np.testing.assert_allclose(streamed, scored.probs, atol=1e-5)  # causal, per sample: the offline numbers
    out = tmp_path / "export"
    written = dict((p.name, what) for p, what in export_all(session, out))
    assert "checked with onnxruntime" in written["classifier_stream.onnx"]
    assert "Default family" in (out / "bundle" / "MODEL_CARD.md").read_text()
    code, lines = classify_files(out / "bundle", [Path(log.source_path)], tmp_path / "p.csv", _options())
    assert code == 0, lines
    pred = pd.read_csv(tmp_path / "p.csv")
    assert len(pred) == log.n_samples
    shipped, which = cycle.shipped_version(session)  # the taught version the export fitted and kept: no second fit
    assert shipped.config["taught_from"] == session.active_model("classifier").id, which
    ships = score_session(session, [log.id], version=shipped)[log.id]  # the session's pass over the shipped one
    np.testing.assert_allclose(pred[[f"p_{c}" for c in bundle.classes]].to_numpy(), ships.probs, atol=1e-4)


class _Rows:
    """A log's step inputs that are not ``SpectralSteps``: ``score_logs`` runs the step pass over them."""

    def __init__(self, steps) -> None:
        self.steps, self.shape = steps, steps.shape

    def __len__(self) -> int:
        return len(self.steps)

    def __getitem__(self, key: slice) -> np.ndarray:
        return self.steps[key]


def test_the_members_once_per_frame_score_as_the_step_pass(session: Session) -> None:
    from training import drift_of_log
    from workbench.cycle.front_end import spectral_features

    if session.active_model("classifier").config["model"] != "default":
        cycle.train_classifier(session, model="default")
    _, bundle = cycle.active_bundle(session)
    predictor = load_bundle(session.path / session.active_model("predictor").path)
    logs = session.logs()
    steps = spectral_features(session, predictor, logs, bundle.spectral)
    surprise = [np.zeros(len(f), np.float32) for f in steps]
    framed = cycle.score_logs(bundle.classifiers, steps, surprise, drift=bundle.drift)
    stepped = cycle.score_logs(bundle.classifiers, [_Rows(f) for f in steps], surprise, drift=bundle.drift)
    for f, a, b in zip(steps, framed, stepped, strict=True):
        np.testing.assert_allclose(a.probs, b.probs, atol=1e-5)
        assert (a.probs.argmax(1) == b.probs.argmax(1)).all()
        np.testing.assert_allclose(a.disagreement, b.disagreement, atol=1e-5)
        np.testing.assert_allclose(a.agreement, b.agreement, atol=1e-6)
        assert b.drift is None  # the step pass computes it only over SpectralSteps
        np.testing.assert_allclose(a.drift, drift_of_log(bundle.drift, bundle.classifiers, f), rtol=1e-5)


def _options():
    from sessions import IngestOptions

    return IngestOptions()


def test_self_training_stretches_hold_no_label_and_no_change_point(session: Session) -> None:
    logs = session.logs()
    segments = session.segments()
    cps = {x.id: signal_change_points(session, x) for x in logs}
    stretches = unlabelled_stretches(logs, segments, lambda x: cps[x.id], shortest=160)
    assert stretches
    for i, a, b in stretches:
        log = logs[i]
        assert 160 <= b - a <= 5 * log.rate_hz
        assert not any(s.log_id == log.id and s.start < b and a < s.stop for s in segments)
        assert not ((cps[log.id] > a) & (cps[log.id] < b)).any()
    units = stretch_units(stretches, lambda i: cps[logs[i].id])
    assert len(units) == len(stretches) and units[0] == 0 and np.all(np.diff(units) >= 0)
    for (i, a, _), (j, _, b), u, v in zip(stretches[1:], stretches, units[1:], units, strict=False):
        # a piece joins the one before it only where they touch in one log with no change point between them
        joined = i == j and a == b and not (cps[logs[i].id] == a).any()
        assert (u == v) == joined
    assert len(set(units)) < len(units)  # some spans longer than 5 s were cut into pieces


def test_the_session_knows_stretches_by_its_scores_and_by_what_it_calls_the_terrains_now(session: Session) -> None:
    """A fit from scratch given the session's scores (their classes taken by today's names) records how many
    stretches the session knows and judges its held-out runs on them (``unseen_runs``, with an interval over runs),
    without being taught them (``RETRAIN.teach`` off); a class the scores do not have is never known."""
    if session.active_model("classifier").config["model"] != "default":
        cycle.train_classifier(session, model="default")
    scores = cycle.compute_scores(session)
    plain = cycle.train_classifier(session, warm_start=False)
    judged = cycle.train_classifier(session, warm_start=False, scores=scores)
    assert 0 < judged.config["known_stretches"] <= judged.config["self_training_stretches"]
    assert not judged.config["taught"] and plain.config["known_stretches"] == 0
    with_known, labels_only = judged.metrics["unseen_runs"], plain.metrics["unseen_runs"]
    assert with_known["samples"] > labels_only["samples"]  # the known stretches scored beside the labels
    assert with_known["runs"] >= 2 and with_known["low"] <= with_known["accuracy"] <= with_known["high"]
    assert with_known["known_stretches"] == judged.config["known_stretches"]
    assert set(with_known["per_run"]) <= {x.name for x in session.logs()}  # by the names the page shows
    logs = cycle.model_logs(session, cycle.active_predictor(session)[1].channels)
    stretches = [(0, 0, 400), (0, 400, 800)]
    classes = list(scores.classes)
    got = cycle.taught_classes(session, scores, logs, [*reversed(classes), "nowhere"], stretches)
    said = np.asarray(scores.scores[logs[0].id].probs[0:400]).argmax(axis=1)
    most = int(np.bincount(said).argmax())
    assert got[0] in (-1, len(classes) - 1 - most)  # the scores' class counted in the fit's order
    assert "nowhere" not in [([*reversed(classes), "nowhere"])[g] for g in got if g >= 0]


def test_stretch_units_cut_at_logs_gaps_and_change_points() -> None:
    stretches = [(0, 0, 500), (0, 500, 1000), (0, 1000, 1400), (0, 1600, 2000), (1, 2000, 2500), (1, 2500, 2900)]
    points = {0: np.asarray([1000]), 1: np.asarray([], np.int64)}
    assert stretch_units(stretches, points.__getitem__) == [0, 0, 1, 2, 3, 3]


def _free_second(session: Session, log) -> int:
    """The start of a labelled-free second of ``log``."""
    taken = [(s.start, s.stop) for s in session.segments() if s.log_id == log.id]
    step = int(log.rate_hz)
    return next(a for a in range(0, log.n_samples - step, step) if not any(s < a + step and a < e for s, e in taken))


def test_a_retrain_after_more_labels_fine_tunes_the_default_models_and_keeps_their_folds(session: Session) -> None:
    base = cycle.train_classifier(session, model="default")  # from scratch: its pieces' folds recorded
    seen = base.config["labels"]
    assert {p[0] for p in seen["pieces"]} == set(seen["ids"]) and {p[3] for p in seen["pieces"]} <= set(range(5))
    old_bundle = load_bundle(session.path / base.path)
    log = session.logs()[1]
    a = _free_second(session, log)
    added = session.add_segment(log.id, a, a + int(log.rate_hz), old_bundle.classes[0], author="test")

    quick = cycle.train_classifier(session, warm_epochs=2)  # what the UI's Retrain asks for
    assert quick.config["warm_start"] is True and quick.config["fine_tuned_from"] == base.id
    assert quick.config["new_labels"] == 1
    kept = quick.config["labels"]["pieces"]
    assert all(p in kept for p in seen["pieces"])  # old segments keep their pieces and folds
    ((_, start, stop, fold),) = [p for p in kept if p[0] == added.id]  # a second is one piece
    assert (start, stop) == (added.start, added.stop) and 0 <= fold < 5
    folds = {added.id: fold}
    assert quick.metrics["out_of_fold"] and "held_out_logs" not in quick.metrics
    assert quick.metrics["n"] == sum(s.length for s in session.segments())
    bundle = load_bundle(session.path / quick.path)
    assert bundle.spectral == old_bundle.spectral and bundle.classes == old_bundle.classes
    changed = [
        not all(torch.equal(p, q) for p, q in zip(m.parameters(), o.parameters(), strict=True))
        for m, o in zip(bundle.classifiers, old_bundle.classifiers, strict=True)
    ]
    assert changed.count(False) == 1 and not changed[folds[added.id]]  # the fold holding it never saw it
    # the refining phase and `workbench train`: from scratch
    assert cycle.train_classifier(session, warm_start=False, warm_epochs=2).config["warm_start"] is False

    # a terrain the active models do not know: a quick fine-tune cannot add a class, so the fit is from scratch
    session.add_terrain("ice")
    b = _free_second(session, log)
    ice = session.add_segment(log.id, b, b + int(log.rate_hz), "ice", author="test")
    reads = Counter()

    def counted(name, fn):
        def call(*args, **kwargs):
            reads[name] += 1
            return fn(*args, **kwargs)

        return call

    import workbench.cycle.fit_inputs as inputs_module
    import workbench.cycle.stage2_fit as fit_module

    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(inputs_module, "active_predictor", counted("predictor", inputs_module.active_predictor))
            mp.setattr(fit_module, "recorded_run", counted("run record", fit_module.recorded_run))
            mp.setattr(session, "segments", counted("labels", session.segments))
            # the quick phase declines (a new terrain) and the fit from scratch runs on what was read: once each
            assert cycle.train_classifier(session, warm_epochs=2).config["warm_start"] is False
        assert reads == {"predictor": 1, "labels": 1, "run record": 1}
    finally:
        session.delete_segment(ice.id, author="test")
        session.delete_segment(added.id, author="test")
        session.remove_terrain("ice")
        session.activate_model(base.id)  # trained on the labels left now: the next test starts where this one did


def test_the_ui_retrain_shows_the_quick_models_then_replaces_them_with_the_fit_from_scratch(session: Session) -> None:
    from workbench.ui.jobs import TrainJob
    from workbench.ui.state import SharedState

    from ..ui.test_ui_state import wait_for

    if session.active_model("classifier").config["model"] != "default":
        cycle.train_classifier(session, model="default")
    state = SharedState(session, on_error=lambda msg: pytest.fail(msg))
    try:
        wait_for(lambda: state.scored and not state.busy)
        log = session.logs()[0]
        a = _free_second(session, log)
        known = load_bundle(session.path / session.active_model("classifier").path).classes[-1]
        added = session.add_segment(log.id, a, a + int(log.rate_hz), known, author="test")
        before = [v.id for v in session.model_versions("classifier")]
        job = TrainJob(state)
        job.start()
        wait_for(lambda: not job.running, timeout=300)
        assert job.status.state == "done", job.status.message
        quick, full = [v for v in session.model_versions("classifier") if v.id not in before]
        assert quick.config["warm_start"] is True and full.config["warm_start"] is False
        assert f"replaced the quick v{quick.id}" in job.status.message
        wait_for(lambda: state.scores.classifier == full.id, timeout=120)
    finally:
        state.stop()
    session.delete_segment(added.id, author="test")


def test_a_version_whose_fold_record_does_not_add_up_is_followed_by_a_fit_from_scratch(session: Session) -> None:
    import json

    base = cycle.train_classifier(session, model="default")
    labels = base.config["labels"]
    cut = {**base.config, "labels": {**labels, "pieces": labels["pieces"][:-1]}}  # a record edited by hand, say
    with session._write() as conn:
        conn.execute("UPDATE model_versions SET config = ? WHERE id = ?", (json.dumps(cut), base.id))
    assert cycle.train_classifier(session, warm_epochs=2).config["warm_start"] is False

    # a version from before blocked folds recorded one fold per segment: a fine-tune reads it as one piece each
    base = session.active_model("classifier")
    labels = base.config["labels"]
    fold = {p[0]: p[3] for p in labels["pieces"]}
    assert len(fold) == len(labels["pieces"])  # the seeded labels are short: one piece each
    older = {**base.config, "labels": {"ids": labels["ids"], "as_of": labels["as_of"]}}
    older["labels"]["folds"] = [fold[i] for i in labels["ids"]]
    with session._write() as conn:
        conn.execute("UPDATE model_versions SET config = ? WHERE id = ?", (json.dumps(older), base.id))
    log = session.logs()[0]
    a = _free_second(session, log)
    session.add_segment(log.id, a, a + int(log.rate_hz), load_bundle(session.path / base.path).classes[0], author="t")
    quick = cycle.train_classifier(session, warm_epochs=2)
    assert quick.config["warm_start"] is True and quick.config["fine_tuned_from"] == base.id
    got = {p[0]: p[3] for p in quick.config["labels"]["pieces"]}
    assert all(got[i] == fold[i] for i in labels["ids"])  # each old segment kept the fold it had


def test_a_third_family_trains_scores_and_exports_in_a_session_with_no_workbench_change(
    session: Session, tmp_path: Path
) -> None:
    """docs/architecture.md's example, a logistic regression on the frames, registered as a room and one line: the
    cycle fits it on the cached frames, scores it and writes its card with nothing in workbench/ changed."""
    from tests.training.third_family import registered

    before = session.active_model("classifier")
    with registered():
        version = cycle.train_classifier(session, model="logreg")
        assert version.config["model"] == "logreg" and version.config["feature_mode"] == "spectral"
        _, bundle = cycle.active_bundle(session)
        assert bundle.family == "logreg" and session.active_model("classifier").id == version.id
        again = cycle.train_classifier(session)  # a Retrain keeps the family; no fine-tune: it fits from scratch
        assert again.config["model"] == "logreg" and again.config["warm_start"] is False
        log = session.logs()[0]
        scored = score_session(session, [log.id])[log.id]
        # its stream is the ONNX module stepped (spectra as cosine and sine products): 1e-4 of the offline FFT; 30
        # hops, four times the 7 frames a step reads, so the stepped state has turned over (as MiniRocket's below)
        streamed = StreamingClassifier(load_bundle(session.path / again.path)).run(
            np.asarray(session.array(log.id))[:600]
        )
        np.testing.assert_allclose(streamed, scored.probs[:600], atol=5e-4)
        written = dict((p.name, what) for p, what in export_all(session, tmp_path / "export"))
        assert "checked with onnxruntime" in written["classifier_stream.onnx"]
        assert "Logreg family" in (tmp_path / "export" / "bundle" / "MODEL_CARD.md").read_text()
    session.activate_model(before.id)  # the session's other tests expect the default active


def test_the_minirocket_family_trains_scores_streams_and_exports_in_a_session(session: Session, tmp_path: Path) -> None:
    """``--model minirocket``: stage 2 on the samples themselves over the default family's stage 1, scored, streamed
    with the offline numbers and exported with its ONNX step checked (840 features: what it does, not how well).
    The module's last test: it leaves the MiniRocket classifier active."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("training.minirocket.rocket_steps_fit.FEATURES", 840)
        version = cycle.train_classifier(session, model="minirocket")
    assert version.config["model"] == "minirocket" and version.config["self_training_stretches"] == 0
    _, bundle = cycle.active_bundle(session)
    assert bundle.family == "minirocket" and bundle.spectral is not None  # the predictor's front end is kept
    assert {"accuracy", "estimate", "calibration"} <= set(version.metrics)
    log = session.logs()[0]
    scored = score_session(session, [log.id])[log.id]
    np.testing.assert_allclose(scored.probs.sum(1), 1.0, atol=1e-5)
    streamed = StreamingClassifier(bundle).run(np.asarray(session.array(log.id))[:600])  # 30 hops
    np.testing.assert_allclose(streamed, scored.probs[:600], atol=1e-5)
    written = dict((p.name, what) for p, what in export_all(session, tmp_path / "export"))
    assert "checked with onnxruntime" in written["classifier_stream.onnx"]
    assert "MiniRocket family" in (tmp_path / "export" / "bundle" / "MODEL_CARD.md").read_text()


def test_model_auto_fits_each_family_over_the_default_stage1_and_keeps_the_better(
    session: Session, tmp_path: Path
) -> None:
    """Issue 65, item 7: ``train --model auto`` fits default and MiniRocket, each a version, and makes active the one
    whose held-out balanced accuracy leads (another family by a point or more), saying both figures and the rule."""
    from workbench.cycle.family_choice import MARGIN, evidence

    assert cycle.auto_families() == ("default", "minirocket")  # the paper's LSTM has a stage 1 of its own
    shares: list[float] = []  # one progress over both families: a bar and its time left run once to 100 %
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("training.minirocket.rocket_steps_fit.FEATURES", 840)
        choice = cycle.train_best_classifier(session, progress=lambda p: shares.append(p.fraction))
    assert shares == sorted(shares) and shares[0] <= 0.5 and shares[-1] == 1.0, shares
    default, rocket = choice.fitted
    assert (default.config["model"], rocket.config["model"]) == ("default", "minirocket")
    a, b = evidence(default.metrics)[0], evidence(rocket.metrics)[0]
    assert a is not None and b is not None
    assert choice.kept.id == (rocket.id if b >= a + MARGIN else default.id)
    assert session.active_model("classifier").id == choice.kept.id and choice.kept.active
    assert f"default balanced {100 * a:.1f} %" in choice.why and f"minirocket balanced {100 * b:.1f} %" in choice.why
    rule = "kept minirocket, ahead of default" if choice.kept.id == rocket.id else "kept default: no other family led"
    assert rule in choice.why, choice.why
    # evidence of a version with no estimate: nothing measured, never a number
    assert evidence({}) == (None, "not measurable")
    cycle.train_classifier(session, model="default")  # the module's later tests start from the default family


def test_a_pick_is_never_shorter_than_what_one_prediction_reads(session: Session) -> None:
    """The scores carry the classifier's input span (the front end's 1.6 s at the log's rate); suggestions and
    verification checks are at least that long, however slow the log (at 6.5 Hz a second is 6 samples, under the 10
    of one window: picks that short taught nothing on a run that changes terrain every few seconds)."""
    scores = cycle.compute_scores(session)
    logs = session.logs()
    front = cycle.active_bundle(session)[1].spectral  # the classifier's front end
    assert scores.span == front.span > 0
    assert cycle.suggestion_lengths(100.0) == (100, 50)
    assert cycle.suggestion_lengths(100.0, span=160) == (160, 160)
    assert cycle.suggestion_lengths(6.5, span=10) == (10, 10)
    picks = cycle.suggest_for_session(session, scores, {}, logs=logs, n=8)
    assert picks and all(p.stop - p.start >= scores.span for _, p in picks)
    checks = cycle.verification_queue(session, scores, logs=logs, n=4)
    assert checks and all(p.stop - p.start >= scores.span for _, p in checks)


def test_classify_names_two_runs_of_one_file_stem_apart(session: Session, tmp_path: Path) -> None:
    """Issue 99, item 1: two files of one stem in two folders were written under one name in CSV and Parquet."""
    import shutil

    export_all(session, tmp_path / "export", taught=False)
    first, second = (Path(x.source_path) for x in session.logs()[:2])
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a, b = shutil.copy(first, tmp_path / "a" / "run.mcap"), shutil.copy(second, tmp_path / "b" / "run.mcap")
    code, lines = classify_files(tmp_path / "export" / "bundle", [Path(a), Path(b)], tmp_path / "p.csv", _options())
    assert code == 0, lines
    assert f"note: two runs are named run: the one from {b} is written as run-2" in lines
    pred = pd.read_csv(tmp_path / "p.csv")
    counts = pred["log"].value_counts().to_dict()
    assert counts == {"run": session.logs()[0].n_samples, "run-2": session.logs()[1].n_samples}
