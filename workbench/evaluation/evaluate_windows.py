"""Evaluation protocols over arrays: the BorealTC authors' partition protocol, and a held-out-logs protocol.

BorealTC (LaRocque et al., IROS 2024): each run is cut into 5 s partitions; partitions are split by stratified
5-fold CV; test partitions are classified in 1.7 s windows with a 0.1 s stride, each window on its own. Here stage 1
trains without labels (on all partitions, or in the strict variant only on the training partitions), and stage 2
sees labels for only a fraction of the training partitions.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from sklearn.model_selection import StratifiedGroupKFold, StratifiedKFold, train_test_split

from training import (
    FeatureMode,
    TrainConfig,
    classification_metrics,
    fit_classifier,
    fit_predictor,
    run_classifiers,
    run_predictor,
)


@dataclass(frozen=True)
class WindowProtocol:
    """Partition and window sizes, in seconds, and the CV."""

    partition_s: float = 5.0
    window_s: float = 1.7
    stride_s: float = 0.1
    folds: int = 5
    train_stride_s: float | None = None  # stage 2 trains on windows at this stride; None: on whole partitions
    frames: int = 7  # default family: frames a step reads (7 frames of 0.4 s every 0.2 s span 1.6 s, for 1.7 s)
    frame_s: float = 0.4  # default family: seconds of one short-time frame (a screen of the front end)


@dataclass
class FoldResult:
    fold: int
    accuracy: float
    macro_f1: float
    windows: int
    labelled_partitions: int
    seconds: float
    metrics: dict


def partitions(
    runs: Sequence[np.ndarray], labels: Sequence[int], size: int
) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Cut runs into consecutive partitions of ``size`` samples (a shorter tail is dropped).

    Returns:
        The partitions, their labels, and the run each came from.
    """
    parts, y, run_of = [], [], []
    for r, (run, label) in enumerate(zip(runs, labels, strict=True)):
        for start in range(0, len(run) - size + 1, size):
            parts.append(run[start : start + size])
            y.append(label)
            run_of.append(r)
    return parts, np.asarray(y), np.asarray(run_of)


def windows(parts: Sequence[np.ndarray], window: int, stride: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Every ``window``-sample window at ``stride`` inside each partition; returns windows and their partition."""
    out, owner = [], []
    for i, p in enumerate(parts):
        for start in range(0, len(p) - window + 1, stride):
            out.append(p[start : start + window])
            owner.append(i)
    return out, np.asarray(owner)


Split = Literal["partitions", "runs"]


def outer_folds(
    y: np.ndarray, run_of: np.ndarray, *, split: Split, folds: int, seed: int
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Stratified folds over partitions (the authors'), or over whole runs: neighbouring partitions of one run look
    alike, and the authors' folds put them on both sides."""
    if split == "runs":
        return list(StratifiedGroupKFold(folds, shuffle=True, random_state=seed).split(np.zeros(len(y)), y, run_of))
    return list(StratifiedKFold(folds, shuffle=True, random_state=seed).split(np.zeros(len(y)), y))


def labelled_subset(train_idx: np.ndarray, y: np.ndarray, labelled: float, *, seed: int) -> np.ndarray:
    """The labelled share of the training partitions, stratified by terrain (all of them when ``labelled >= 1``)."""
    if labelled >= 1.0:
        return np.asarray(train_idx)
    chosen, _ = train_test_split(train_idx, train_size=labelled, stratify=y[train_idx], random_state=seed)
    return np.asarray(chosen)


def classify_windows(
    pfit, cfit, feature_mode: FeatureMode, wins: Sequence[np.ndarray], *, device: str = "cpu"
) -> np.ndarray:
    """Each window through both stages from a zero state; the class at its last step. ``(N,)``"""
    preds = []
    for i in range(0, len(wins), 2048):
        chunk = wins[i : i + 2048]
        outs = run_predictor(pfit.model, pfit.normalizer, chunk, batch=512, device=device)
        probs = run_classifiers(cfit.models, [o.features(feature_mode) for o in outs], batch=512, device=device)
        preds.extend(p.mean(0)[-1].argmax() for p in probs)
    return np.asarray(preds)


def borealtc_protocol(
    runs: Sequence[np.ndarray],
    labels: Sequence[int],
    classes: Sequence[str],
    *,
    rate_hz: float,
    labelled: float = 0.1,
    strict: bool = False,
    protocol: WindowProtocol = WindowProtocol(),
    stage1: TrainConfig | None = None,
    stage2: TrainConfig | None = None,
    hidden: int = 200,
    feature_mode: FeatureMode = "hidden",
    split: Split = "partitions",
    seed: int = 0,
    log: Callable[[str], None] = print,
) -> list[FoldResult]:
    """Run the protocol; one result per outer fold.

    Args:
        runs: One ``(T, C)`` array per run, raw units.
        labels: The terrain (class index) of each run.
        classes: Class names.
        rate_hz: Sample rate of the runs.
        labelled: Fraction of the training partitions whose labels stage 2 sees (stratified by terrain).
        strict: Stage 1 never sees the test partitions (else it trains once on all partitions' signals).
        protocol: Partition / window sizes and number of folds.
        stage1: Training settings of stage 1.
        stage2: Training settings of stage 2 (its context is 0 and its pieces are windows: it is tested on
            windows classified on their own).
        hidden: LSTM width of both stages.
        feature_mode: What stage 1 hands stage 2.
        split: ``"partitions"`` (the authors' folds) or ``"runs"`` (whole runs held out).
        seed: Seed of the folds, the labelled subset and training.
        log: Where progress lines go.
    """
    rate = rate_hz
    size, win, stride = (
        round(protocol.partition_s * rate),
        round(protocol.window_s * rate),
        round(protocol.stride_s * rate),
    )
    parts, y, run_of = partitions(runs, labels, size)
    stage1 = stage1 or TrainConfig(max_epochs=40, patience=5, seed=seed)
    stage2 = replace(stage2 or TrainConfig(max_epochs=150, patience=15, seed=seed), context=0, label_piece=win)
    shared = None
    if not strict:
        t = time.monotonic()
        shared = fit_predictor(parts, config=replace(stage1, piece=size), hidden=hidden)
        log(
            f"stage 1 on all {len(parts)} partitions (no labels): {len(shared.history)} epochs, "
            f"{time.monotonic() - t:.0f} s"
        )
    results = []
    for fold, (train_idx, test_idx) in enumerate(
        outer_folds(y, run_of, split=split, folds=protocol.folds, seed=seed), start=1
    ):
        t0 = time.monotonic()
        pfit = shared or fit_predictor([parts[i] for i in train_idx], config=replace(stage1, piece=size), hidden=hidden)
        chosen = labelled_subset(train_idx, y, labelled, seed=seed + fold)
        if protocol.train_stride_s is None:
            train_seqs, train_y = [parts[i] for i in chosen], y[chosen]
        else:
            # Stage 2 sees what it is tested on: windows whose stage-1 features start from a zero state. Features
            # of a whole partition carry a warmed-up stage-1 state that no test window has.
            train_seqs, owner = windows([parts[i] for i in chosen], win, round(protocol.train_stride_s * rate))
            train_y = y[chosen][owner]
        outs = run_predictor(pfit.model, pfit.normalizer, train_seqs, batch=512, device=stage1.device)
        feats = [o.features(feature_mode) for o in outs]
        segments = [(j, 0, len(s), int(c)) for j, (s, c) in enumerate(zip(train_seqs, train_y, strict=True))]
        cfit = fit_classifier(feats, segments, classes, config=stage2, hidden=hidden)
        test_wins, owner = windows([parts[i] for i in test_idx], win, stride)
        y_true = y[test_idx][owner]
        y_pred = classify_windows(pfit, cfit, feature_mode, test_wins, device=stage2.device)
        m = classification_metrics(y_true, y_pred, classes)
        results.append(
            FoldResult(fold, m["accuracy"], m["macro_f1"], len(test_wins), len(chosen), time.monotonic() - t0, m)
        )
        log(
            f"fold {fold}: accuracy {m['accuracy']:.2%}, macro-F1 {m['macro_f1']:.3f} on {len(test_wins)} windows "
            f"({len(chosen)} labelled partitions, {time.monotonic() - t0:.0f} s)"
        )
    return results
