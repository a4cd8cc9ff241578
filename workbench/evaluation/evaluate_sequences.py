"""Protocols over labelled sequences: the paper's QCAT split, and held-out logs with per-timestep truth."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from training import (
    FeatureMode,
    TrainConfig,
    classification_metrics,
    fit_classifier,
    fit_predictor,
    run_classifiers,
    run_predictor,
)


def _split_groups(groups: np.ndarray, fractions: Sequence[float], rng: np.random.Generator) -> list[np.ndarray]:
    """Split item indices by whole groups into parts of about ``fractions`` of the items."""
    uniq = rng.permutation(np.unique(groups))
    sizes = np.array([np.sum(groups == g) for g in uniq])
    bounds = np.cumsum(fractions)[:-1] * sizes.sum()
    part = np.searchsorted(bounds, np.cumsum(sizes) - sizes / 2)
    return [np.flatnonzero(np.isin(groups, uniq[part == k])) for k in range(len(fractions))]


def qcat_protocol(
    sequences: Sequence[np.ndarray],
    labels: Sequence[int],
    groups: Sequence[int],
    classes: Sequence[str],
    *,
    leak_free: bool = False,
    folds: int = 5,
    stage1: TrainConfig | None = None,
    stage2: TrainConfig | None = None,
    hidden: int = 200,
    feature_mode: FeatureMode = "hidden",
    seed: int = 0,
    log: Callable[[str], None] = print,
) -> list[dict]:
    """The paper's split, repeated ``folds`` times: 90 % unlabelled for stage 1, 5 % labelled for stage 2, 5 % test.

    Each sequence (a step of a trial) is classified from a zero state; its class is the ensemble's at the last step.
    With ``leak_free`` whole trials (``groups``) go to one side, so no trial is both trained and tested on.
    """
    y = np.asarray(labels)
    g = np.asarray(groups) if leak_free else np.arange(len(y))
    stage1 = stage1 or TrainConfig(max_epochs=60, patience=8, seed=seed)
    longest = max(len(s) for s in sequences)
    stage2 = replace(stage2 or TrainConfig(max_epochs=150, patience=15, seed=seed), context=0, label_piece=longest)
    results = []
    for fold in range(1, folds + 1):
        t0 = time.monotonic()
        rng = np.random.default_rng(seed + fold)
        unl, lab, test = _split_groups(g, (0.9, 0.05, 0.05), rng)
        pfit = fit_predictor([sequences[i] for i in unl], config=replace(stage1, piece=longest), hidden=hidden)
        outs = run_predictor(
            pfit.model, pfit.normalizer, [sequences[i] for i in np.r_[lab, test]], batch=512, device=stage1.device
        )
        feats = [o.features(feature_mode) for o in outs]
        segments = [(j, 0, len(sequences[i]), int(y[i])) for j, i in enumerate(lab)]
        cfit = fit_classifier(feats[: len(lab)], segments, classes, config=stage2, hidden=hidden)
        probs = run_classifiers(cfit.models, feats[len(lab) :], batch=512, device=stage2.device)
        pred = np.array([p.mean(0)[-1].argmax() for p in probs])
        m = classification_metrics(y[test], pred, classes)
        m.update(fold=fold, sequences=(len(unl), len(lab), len(test)), seconds=time.monotonic() - t0)
        results.append(m)
        log(
            f"fold {fold}: accuracy {m['accuracy']:.2%}, macro-F1 {m['macro_f1']:.3f} on {len(test)} test sequences "
            f"({len(lab)} labelled, {len(unl)} unlabelled)"
        )
    return results


def held_out_logs_protocol(
    logs: Sequence[np.ndarray],
    truth: Sequence[np.ndarray],
    classes: Sequence[str],
    *,
    labelled: float = 0.05,
    segment: int = 300,
    folds: int = 5,
    modes: Sequence[FeatureMode] = ("hidden",),
    stage1: TrainConfig | None = None,
    stage2: TrainConfig | None = None,
    hidden: int = 200,
    seed: int = 0,
    log: Callable[[str], None] = print,
) -> dict[str, list[dict]]:
    """Leave-logs-out folds with per-timestep truth (``-1`` = unknown); one result list per feature mode.

    Stage 1 trains once on all logs (no labels). In each fold, stage 2 sees ``labelled`` of the training logs' time
    as random ``segment``-sample stretches of known terrain, then whole held-out logs are classified step by step.
    """
    stage1 = stage1 or TrainConfig(max_epochs=40, patience=5, seed=seed)
    stage2 = stage2 or TrainConfig(max_epochs=150, patience=15, seed=seed)
    pfit = fit_predictor(list(logs), config=stage1, hidden=hidden)
    log(f"stage 1 on {len(logs)} logs: {len(pfit.history)} epochs")
    outs = run_predictor(pfit.model, pfit.normalizer, list(logs), device=stage1.device)
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(logs))
    splits = np.array_split(order, min(folds, len(logs)))
    results: dict[str, list[dict]] = {m: [] for m in modes}
    for fold, test in enumerate(splits, start=1):
        train = np.setdiff1d(order, test)
        budget = labelled * sum(len(logs[i]) for i in train)
        segments, taken = [], 0
        while taken < budget:
            i = int(rng.choice(train))
            s = int(rng.integers(0, len(logs[i]) - segment))
            lab = truth[i][s : s + segment]
            if lab[0] < 0 or (lab != lab[0]).any():
                continue  # a stretch of one known terrain, as a person would label
            segments.append((int(np.flatnonzero(train == i)[0]), s, s + segment, int(lab[0])))
            taken += segment
        for mode in modes:
            feats = [outs[i].features(mode) for i in train]
            cfit = fit_classifier(feats, segments, classes, config=replace(stage2, seed=seed + fold), hidden=hidden)
            probs = run_classifiers(cfit.models, [outs[i].features(mode) for i in test], device=stage2.device)
            y_true = np.concatenate([truth[i] for i in test])
            y_pred = np.concatenate([p.mean(0).argmax(-1) for p in probs])
            known = y_true >= 0
            m = classification_metrics(y_true[known], y_pred[known], classes)
            m.update(fold=fold, labelled_segments=len(segments))
            results[mode].append(m)
            log(f"fold {fold} [{mode}]: accuracy {m['accuracy']:.2%}, macro-F1 {m['macro_f1']:.3f}")
    return results
