"""The default family's quick Retrain: the active fold models fine-tuned on the labels added since, in seconds.

A from-scratch fit (:func:`.fit_window.fit_window_classifier`) trains every fold model twice (labels, then
pseudo-labels) and as many again on folds over logs: minutes on a big session. After a few more labels the active
models already fit every older one, so each fold model takes a short run of AdamW steps on the new labels it may
see and as many older rows replayed (so it does not drift off what it knew); the from-scratch fit follows in the
background (the UI's refining phase).

The fold of each segment carries over from the version fine-tuned: a fold model never trains on a segment of its
own fold, old or new, so the out-of-fold figures stay honest. New segments join the fold with fewest segments of
their terrain.
"""

from __future__ import annotations

import copy
import itertools
import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ..figures import classification_metrics
from ..fitting import ClassifierFit, Segment
from ..running import CancelFn, Cancelled, Progress, ProgressFn, never
from .class_balance import class_shares
from .fit_window import HELD_ROWS, predict_steps, row_logits
from .spectra import SpectralSteps
from .stretch_pool import every_row
from .window_classifier import WindowClassifier
from .window_config import WindowFitConfig
from .window_drift import fit_drift, held_out_relation
from .window_rows import at_most, window_rows
from .window_train import train_rows


def assign_folds(labels: Sequence[int], known: Sequence[int], k: int) -> list[int]:
    """The fold of every segment: ``known[i]`` where it is one (``0 <= known[i] < k``), else the fold holding the
    fewest segments of its terrain so far (then the fewest segments; then the lowest), in order.

    Args:
        labels: Class of each segment.
        known: Fold of each segment in the version fine-tuned, ``-1`` for a new one.
        k: Folds (the number of fold models).
    """
    folds = [int(f) if 0 <= f < k else -1 for f in known]
    per_class: dict[int, np.ndarray] = {}
    size = np.zeros(k, np.int64)
    for label, f in zip(labels, folds, strict=True):
        if f >= 0:
            per_class.setdefault(int(label), np.zeros(k, np.int64))[f] += 1
            size[f] += 1
    for i, (label, f) in enumerate(zip(labels, folds, strict=True)):
        if f < 0:
            counts = per_class.setdefault(int(label), np.zeros(k, np.int64))
            f = int(np.lexsort((np.arange(k), size, counts))[0])
            folds[i] = f
            counts[f] += 1
            size[f] += 1
    return folds


def fine_tune_window_classifier(
    features: Sequence[SpectralSteps],
    segments: Sequence[Segment],
    classes: Sequence[str],
    previous: Sequence[WindowClassifier],
    *,
    folds: Sequence[int],
    new: Sequence[int],
    steps: int,
    lr_scale: float,
    config: WindowFitConfig | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ClassifierFit:
    """Fine-tune each fold model on the new segments outside its fold, with as many older rows replayed.

    Args:
        features: Per log, its per-step spectral frames (the front end of ``previous``).
        segments: Every labelled stretch ``(log index, start, stop, class index)``.
        classes: The ``K`` class names (those of ``previous``).
        previous: The active fold models; their standardisation is kept.
        folds: Fold of each segment (:func:`assign_folds`): fold model ``m`` never trains on fold ``m``.
        new: Indices into ``segments`` added or changed since ``previous`` trained.
        steps: AdamW steps per fold model (``config.batch`` rows each).
        lr_scale: The fine-tune's learning rate as a share of ``config.lr``.
        config: Batch, learning rate, weight decay, noise and seed (as a from-scratch fit's).
        progress: Called after each fold model.
        cancel: Polled between fold models and epochs.

    Returns:
        The fine-tuned ensemble and out-of-fold metrics over every labelled step, each predicted by the fold model
        that never trained on it. A fold model with no new segment to learn from is the previous one, unchanged.
    """
    config = config or WindowFitConfig()
    k = len(previous)
    if len(folds) != len(segments) or any(not 0 <= f < k for f in folds):
        raise ValueError(f"every segment needs a fold in 0..{k - 1}")
    if any(m.config.n_classes != len(classes) for m in previous):
        raise ValueError("the previous models have other classes: fit from scratch")
    t0 = time.monotonic()
    fold_of = np.asarray(folds)
    is_new = np.zeros(len(segments), bool)
    is_new[list(new)] = True
    # one row per completed frame, each segment's frames held once (a fleet's labels stacked would be 7 times that)
    every, ends = window_rows(features, [s[:3] for s in segments], every_row)
    rows = [np.arange(a, b) for a, b in itertools.pairwise(ends)]  # each segment's rows in ``every``
    rng = np.random.default_rng(config.seed)
    # the balance evens out the whole label set's shares, not those of the new labels and their replayed rows
    prior = class_shares(
        np.concatenate([np.full(len(r), s[3]) for r, s in zip(rows, segments, strict=True)]), len(classes)
    )
    tune = replace(config, lr=config.lr * lr_scale, max_steps=steps)
    models = []
    for m, old in enumerate(previous):
        if cancel():
            raise Cancelled("classifier training cancelled")
        learn = np.flatnonzero(is_new & (fold_of != m))
        model = copy.deepcopy(old).eval()
        if len(learn):
            x_new = np.concatenate([rows[i] for i in learn])  # indices into ``every``, stacked when drawn
            y_new = np.concatenate([np.full(len(rows[i]), segments[i][3]) for i in learn])
            keep = np.flatnonzero(~is_new & (fold_of != m))
            if len(keep) and len(x_new):
                x_old = np.concatenate([rows[i] for i in keep])
                y_old = np.concatenate([np.full(len(rows[i]), segments[i][3]) for i in keep])
                take = rng.choice(len(x_old), min(len(x_old), max(len(x_new), config.batch)), replace=False)
                x_new, y_new = np.concatenate([x_new, x_old[take]]), np.concatenate([y_new, y_old[take]])
            x_new = every.take(x_new)
            if len(x_new):
                model = train_rows(model, x_new, y_new, steps, tune, config.seed + m + 1, cancel, prior=prior)
        models.append(model)
        if progress:
            progress(Progress("classifier", m + 1, k, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))
    true, pred = [], []
    for i, (seq, a, b, label) in enumerate(segments):
        true.append(np.full(b - a, label))
        pred.append(predict_steps(models[fold_of[i]], features[seq], a, b))
    metrics = classification_metrics(np.concatenate(true), np.concatenate(pred), classes)
    metrics["out_of_fold"] = k > 1
    metrics["n_segments"] = len(segments)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    metrics["new_segments"] = int(is_new.sum())
    history = [[{"steps": steps, "new_segments": int((is_new & (fold_of != m)).sum())}] for m in range(k)]

    def stacked(which: np.ndarray, most: int, draw: int) -> tuple[np.ndarray, np.ndarray]:
        """The rows of segments ``which``, at most ``most`` of them (a seeded draw), and their classes."""
        idx = np.concatenate([rows[i] for i in which] or [np.zeros(0, np.int64)]).astype(np.int64)
        y = np.concatenate([np.full(len(rows[i]), segments[i][3]) for i in which] or [np.zeros(0, np.int64)])
        pick = at_most(len(idx), most, (config.seed, draw))  # a fleet's labels stacked per member would not fit
        return every.take(idx[pick]), y[pick]

    # the members' embeddings moved: the drift reference is drawn again from the rows each one trained on
    trained = [stacked(np.flatnonzero(fold_of != m), config.reference_rows, m)[0] for m in range(k)]
    held_xy = [stacked(np.flatnonzero(fold_of == m) if k > 1 else [], HELD_ROWS, k + m) for m in range(k)]
    held = [x for x, _ in held_xy]
    if not any(len(t) for t in trained):  # a single fold model trains on its own fold
        trained = [stacked(np.arange(len(segments)), config.reference_rows, 2 * k)[0]] * k
    drift = fit_drift(models, trained, held, seed=config.seed, rows_kept=config.reference_rows)
    if k > 1:
        right = [row_logits(model, x).argmax(1) == y for model, (x, y) in zip(models, held_xy, strict=True)]
        if relation := held_out_relation(drift, models, held, right):
            metrics["drift_accuracy"] = relation
    return ClassifierFit(
        models,
        metrics,
        history,
        [np.flatnonzero(fold_of == m).tolist() for m in range(k)],  # type: ignore[arg-type]
        drift=drift,
    )
