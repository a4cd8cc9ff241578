"""Modules and fits at tiny sizes: shapes, causality, state carrying, and that training actually learns."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from training import (
    Cancelled,
    Classifier,
    ClassifierConfig,
    Normalizer,
    Piece,
    Predictor,
    PredictorConfig,
    TrainConfig,
    cut_pieces,
    fit_classifier,
    fit_predictor,
    fold_indices,
    neighbour_pairs,
    run_classifiers,
    run_predictor,
    stage1_batch,
)

TINY = TrainConfig(max_epochs=3, patience=2, chunk=16, piece=64, batch_size=8, label_piece=32, context=8, k_folds=3)


def sine_logs(n_logs: int = 3, t: int = 300, c: int = 3, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_logs):
        tt = np.arange(t)[:, None]
        out.append(
            (np.sin(tt * (0.1 + 0.05 * np.arange(c)) + i) * 3 + 10 + 0.1 * rng.normal(size=(t, c))).astype(np.float32)
        )
    return out


def test_predictor_is_causal_and_chunking_carries_state() -> None:
    torch.manual_seed(0)
    model = Predictor(PredictorConfig(3, 8)).eval()
    x = torch.randn(2, 40, 3)
    est, hid, _ = model(x)
    assert est.shape == (2, 40, 3) and hid.shape == (2, 40, 8)
    x2 = x.clone()
    x2[:, 25:] += 5.0  # change the future
    est2, _, _ = model(x2)
    torch.testing.assert_close(est[:, :25], est2[:, :25])  # the past does not see it
    a, _, state = model(x[:, :17])
    b, _, _ = model(x[:, 17:], state)
    torch.testing.assert_close(torch.cat([a, b], 1), est)


def test_classifier_shapes_and_dropout_only_in_training() -> None:
    model = Classifier(ClassifierConfig(8, 4, 8, 0.2))
    f = torch.randn(3, 20, 8)
    logits, _ = model(f)
    assert logits.shape == (3, 20, 4)
    model.eval()
    torch.testing.assert_close(model(f)[0], model(f)[0])


def test_normalizer_and_stage1_targets_are_the_next_sample() -> None:
    logs = sine_logs()
    norm = Normalizer.fit(logs)
    z = np.concatenate([norm(a) for a in logs])
    np.testing.assert_allclose(z.mean(0), 0, atol=1e-4)
    np.testing.assert_allclose(z.std(0), 1, atol=1e-3)
    pieces = cut_pieces([len(a) for a in logs], 128)
    _, y, mask = stage1_batch(logs, pieces, 128)
    p = pieces[0]
    np.testing.assert_array_equal(y[0, :10], logs[p.seq][p.start + 1 : p.start + 11])
    last = pieces[-1]  # ends at its log's end: the final step has no target
    assert mask[len(pieces) - 1, last.length - 2] and not mask[len(pieces) - 1, last.length - 1]


def test_predictor_learns_and_reports_progress() -> None:
    logs = sine_logs()
    seen = []
    fit = fit_predictor(logs, config=TrainConfig(**{**TINY.__dict__, "max_epochs": 12}), hidden=8, progress=seen.append)
    losses = [h["val_loss"] for h in fit.history]
    assert losses[-1] < 0.6 * losses[0]  # normalised units: 1.0 is predicting the mean
    assert seen and seen[-1].stage == "predictor" and 0 < seen[-1].fraction <= 1
    outs = run_predictor(fit.model, fit.normalizer, logs)
    assert outs[0].hidden.shape == (300, 8) and outs[0].error.shape == (300, 3)
    assert np.all(outs[0].error[0] == 0)


def test_cancel_stops_training() -> None:
    with pytest.raises(Cancelled):
        fit_predictor(sine_logs(), config=TINY, hidden=8, cancel=lambda: True)


def test_folds_never_split_a_segment_and_are_stratified() -> None:
    labels = [0, 0, 0, 1, 1, 1, 2, 2, 2]
    folds = fold_indices(labels, 3, seed=0)
    assert len(folds) == 3
    seen = sorted(i for _, val in folds for i in val)
    assert seen == list(range(9))  # each segment validated exactly once
    for train, val in folds:
        assert not set(train) & set(val)
        assert sorted(labels[i] for i in val) == [0, 1, 2]
    assert len(fold_indices([0, 1], 5, seed=0)) == 2  # fewer segments than k: one per fold
    ((train, val),) = fold_indices([0], 5, seed=0)
    assert list(train) == list(val) == [0]


def test_classifier_separates_two_easy_classes_from_sparse_labels() -> None:
    rng = np.random.default_rng(1)
    # class 0: low-variance noise, class 1: high-variance noise; alternating 100-step stretches
    feats, truth = [], []
    for _ in range(2):
        y = np.repeat(np.arange(8) % 2, 100)
        f = rng.normal(size=(800, 4)) * np.where(y[:, None] == 1, 2.0, 0.3)
        feats.append(f.astype(np.float32))
        truth.append(y)
    segments = [
        (0, 10, 90, 0),
        (0, 110, 190, 1),
        (0, 410, 490, 0),
        (0, 510, 590, 1),
        (0, 610, 690, 0),
        (0, 710, 790, 1),
    ]
    fit = fit_classifier(
        feats,
        segments,
        ["calm", "rough"],
        config=TrainConfig(**{**TINY.__dict__, "max_epochs": 40, "patience": 10, "context": 100}),
        hidden=8,
    )
    assert len(fit.models) == 3
    assert fit.metrics["out_of_fold"] and fit.metrics["n_segments"] == 6
    probs = run_classifiers(fit.models, [feats[1]])[0]  # (M, T, K) on a log it never saw
    assert probs.shape == (3, 800, 2)
    acc = (probs.mean(0).argmax(-1) == truth[1]).mean()
    assert acc > 0.8


def test_length_batches_cover_every_piece_once_in_batches_of_like_length() -> None:
    from training.paper_lstm.classifier_fit import length_batches

    lengths = np.random.default_rng(0).integers(100, 661, 130).astype(np.float64)
    batches = length_batches(lengths, 32, np.random.default_rng(1))
    assert sorted(np.concatenate(batches).tolist()) == list(range(130))
    assert [len(b) for b in sorted(batches, key=len)] == [2, 32, 32, 32, 32]
    padded = sum(len(b) * lengths[b].max() for b in batches)
    mixed = sum(len(b) * lengths[b].max() for b in np.array_split(np.random.default_rng(2).permutation(130), 5))
    assert padded < 0.8 * mixed  # less padding than random batches
    again = length_batches(lengths, 32, np.random.default_rng(1))
    assert all(np.array_equal(a, b) for a, b in zip(batches, again, strict=True))


def test_a_fine_tune_trains_on_new_segments_with_as_many_old_ones_replayed() -> None:
    from training.paper_lstm.classifier_fit import _epoch_pieces

    cfg = TrainConfig(**{**TINY.__dict__, "label_piece": 50, "context": 0})
    new = [(0, 0, 100, 1)]  # 2 crops
    old = [(1, i * 100, i * 100 + 100, 0) for i in range(40)]  # 80 crops
    rng = np.random.default_rng(0)
    pieces = _epoch_pieces(new, old, cfg, rng)
    assert sum(p.seq == 0 for p in pieces) == 2 and sum(p.seq == 1 for p in pieces) == 32  # at least a batch
    assert len(_epoch_pieces(new * 40, old, cfg, rng)) == 80 + 80
    assert _epoch_pieces([], old, cfg, rng) == []  # nothing new: nothing to train


def test_neighbour_pairs_are_gap_apart_and_never_compare_across_a_boundary() -> None:
    pairs = neighbour_pairs([100, 29, 60], window=10, gap=20, stride=5, boundaries=[[50], [], [31]])
    assert pairs, "some pairs fit"
    for a, b in pairs:
        assert a.seq == b.seq and a.label == b.label == -1
        assert a.length == b.length == 10 and b.start - a.start == 20 and a.loss_from == a.start
        assert b.stop <= [100, 29, 60][a.seq]
        cut = {0: 50, 2: 31}.get(a.seq)
        assert cut is None or not a.stop - 1 < cut <= b.stop - 1  # the compared last steps on one side of it
    starts = {(a.seq, a.start) for a, _ in pairs}
    # log 0: starts 0..70 by 5; last steps s + 9 and s + 29. The boundary 50 splits them for s = 25..40, not for
    # s = 20 (it comes after both) nor s = 45 (inside the first window, before both last steps)
    assert {s for q, s in starts if q == 0} == {0, 5, 10, 15, 20, 45, 50, 55, 60, 65, 70}
    assert not any(q == 1 for q, _ in starts)  # 29 samples hold no pair of 10 + 20
    # log 2: starts 0..30; the boundary 31 splits s = 5 (last steps 14, 34) .. 20 (29, 49), not s = 0 (9, 29: it
    # comes after both) nor s = 25, 30 (34, 54 and 39, 59: before both, inside the first window)
    assert {s for q, s in starts if q == 2} == {0, 25, 30}
    assert len(neighbour_pairs([100], window=10, gap=20, stride=5)) == 15  # no boundaries known: every start
    with pytest.raises(ValueError, match="positive"):
        neighbour_pairs([100], window=10, gap=0, stride=5)


def test_consistency_pulls_the_paired_windows_predictions_together() -> None:
    rng = np.random.default_rng(3)
    # feature 0 tells the classes apart; the labels say low = class 0, high = class 1
    low = rng.normal(-1.0, 0.3, size=(200, 3)).astype(np.float32)
    high = rng.normal(1.0, 0.3, size=(200, 3)).astype(np.float32)
    feats = [low, high, np.concatenate([low, high])]
    segments = [(log, a, a + 50, log) for log in (0, 1) for a in range(0, 200, 50)]
    # the pairs join windows of the unlabelled log 2 across its low/high halves, against what the labels teach
    pairs = [(Piece(2, s, s + 40, s), Piece(2, s + 200, s + 240, s + 200)) for s in range(0, 160, 10)]

    def pair_distance(weight: float) -> float:
        cfg = TrainConfig(
            **{
                **TINY.__dict__,
                "max_epochs": 30,
                "patience": 30,
                "context": 0,
                "label_piece": 40,
                "consistency": weight,
            }
        )
        fit = fit_classifier(feats, segments, ["low", "high"], config=cfg, hidden=8, pairs=pairs)
        windows = [feats[2][a.start : a.stop] for a, _ in pairs] + [feats[2][b.start : b.stop] for _, b in pairs]
        probs = run_classifiers(fit.models, windows)  # per window (M, 40, K)
        last = np.array([p.mean(0)[-1] for p in probs])  # (2P, K)
        return float(np.square(last[: len(pairs)] - last[len(pairs) :]).sum(-1).mean())

    without, with_term = pair_distance(0.0), pair_distance(20.0)
    assert without > 0.5  # labels alone: the halves get different classes
    assert with_term < 0.5 * without
