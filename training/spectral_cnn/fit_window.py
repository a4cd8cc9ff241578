"""Stage 2 of the default family: the window classifier from labelled segments and, by self-training, from
unlabelled stretches too; a k-fold ensemble with out-of-fold metrics, as the paper family's stage 2.

Each fold is a small network (:class:`.window_classifier.WindowClassifier`) trained with AdamW on the frame
rows of its segments: a step's input changes only when a frame completes, so one row per frame is the whole training
set, with no repeats. Weight decay, dropout and input noise regularise it; the settings were chosen on BorealTC's
inner folds (``benchmarks/default_family_cnn.py``), never on its test folds.

Self-training, a fixed rule measured on BorealTC at 10 % of labels (+1.6 points on the authors' folds and +0.5 on
unseen runs for the network; ``benchmarks/default_family_ablation.py``): each fold model labels every unlabelled
stretch (a span with no change point and no label); a stretch whose frames agree on one terrain (``agree`` of them)
lends it to all of its frames, and the fold is trained again on its labels and these pseudo-labels. Its out-of-fold
figures stay honest: stretches never hold a labelled step.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence

import numpy as np
import torch
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold
from torch.nn import functional as F

from ..fitting import ClassifierFit, Segment, fold_indices
from ..metrics import classification_metrics
from ..progress import CancelFn, Cancelled, Progress, ProgressFn, never
from .spectra import SpectralSteps
from .window_classifier import WindowClassifier, WindowClassifierConfig
from .window_config import WindowFitConfig

PSEUDO_STRIDE = 3  # rows of a stretch self-training reads: every third frame
PREDICT_CHUNK = 4096  # steps per call when scoring segments: bounds the stacked frames in memory
Stretch = tuple[int, int, int]  # (log index, start, stop): unlabelled, no change point inside


def frame_rows(features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """The distinct inputs of steps ``[start, stop)``: one per completed frame (the last step when none)."""
    steps = features.frame_rows(start, stop)
    if len(steps) == 0 and stop - 1 >= features.config.frame - 1:
        steps = np.asarray([stop - 1])
    if len(steps) == 0:
        return np.zeros((0, features.shape[1]), np.float32)
    block = features[int(steps[0]) : int(steps[-1]) + 1]
    return block[steps - steps[0]]


def _moments(features: Sequence[SpectralSteps]) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and spread of a frame over every frame of every log, summed a log at a time: a fleet's
    frames never sit in memory together."""
    n, total, total_sq = 0, 0.0, 0.0
    for f in features:
        rows = np.asarray(f.frames, np.float64)  # (N, F) of one log
        n += len(rows)
        total = total + rows.sum(0)
        total_sq = total_sq + np.square(rows).sum(0)
    mean = total / max(n, 1)
    std = np.sqrt(np.maximum(total_sq / max(n, 1) - np.square(mean), 0.0))
    return np.asarray(mean, np.float32), np.asarray(std, np.float32)


def train_rows(
    model: WindowClassifier,
    x: np.ndarray,
    y: np.ndarray,
    epochs: int,
    config: WindowFitConfig,
    seed: int,
    cancel: CancelFn,
) -> WindowClassifier:
    """``epochs`` passes of AdamW over rows ``x (N, W·F)`` with classes ``y (N,)`` (at most ``config.max_steps``)."""
    gen = torch.Generator().manual_seed(seed)
    xt, yt = torch.from_numpy(np.ascontiguousarray(x, np.float32)), torch.from_numpy(np.asarray(y, np.int64))
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    per_epoch = -(-len(xt) // config.batch)
    epochs = max(1, min(epochs, config.max_steps // max(per_epoch, 1)))
    noise_scale = config.noise / model.in_scale.repeat(model.config.window)  # (W·F,) standardised units, raw scale
    model.train()
    left = config.max_steps  # an epoch longer than the budget (a huge label set) stops part-way
    for _ in range(epochs):
        if cancel():
            raise Cancelled("classifier training cancelled")
        for idx in torch.randperm(len(xt), generator=gen).split(config.batch)[:left]:
            left -= 1
            xb = xt[idx]
            xb = xb + torch.randn(xb.shape, generator=gen) * noise_scale
            loss = F.cross_entropy(model.logits(xb), yt[idx])
            opt.zero_grad()
            loss.backward()
            opt.step()
        if not torch.isfinite(loss):
            raise ValueError("the window classifier's training diverged (a non-finite loss)")
    return model.eval()


@torch.inference_mode()
def predict_steps(model: WindowClassifier, features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """Classes of steps ``[start, stop)`` of one log, as the offline passes score them (a chunk at a time)."""
    out = []
    for c in range(start, stop, PREDICT_CHUNK):
        chunk = torch.from_numpy(features[c : min(c + PREDICT_CHUNK, stop)])[None]  # (1, L, D)
        out.append(model(chunk)[0][0].argmax(1).numpy())
    return np.concatenate(out) if out else np.zeros(0, np.int64)


@torch.inference_mode()
def _predict_rows(model: WindowClassifier, x: np.ndarray) -> np.ndarray:
    """Classes of rows ``(N, W·F)``."""
    if len(x) == 0:
        return np.zeros(0, np.int64)
    chunks = np.array_split(x, -(-len(x) // PREDICT_CHUNK))
    return torch.cat([model.logits(torch.from_numpy(c)).argmax(1) for c in chunks]).numpy()


def _pseudo_labels(
    model: WindowClassifier, stretch_rows: Sequence[np.ndarray], agree: float
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    xs, ys = [], []
    k = model.config.n_classes
    for rows in stretch_rows:
        if len(rows) == 0:
            continue
        counts = np.bincount(_predict_rows(model, rows), minlength=k)
        if counts.max() >= agree * len(rows):
            xs.append(rows)
            ys.append(np.full(len(rows), counts.argmax()))
    return xs, ys


def _log_folds(segments: Sequence[Segment], k: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Folds over segments that hold out whole logs (at most ``k``), terrains spread over them as evenly as whole
    logs allow; none when fewer than two logs are labelled or a fold's training part would hold one terrain only."""
    logs = np.asarray([s[0] for s in segments])
    n_logs = len(np.unique(logs))
    if n_logs < 2:
        return []
    labels = np.asarray([s[3] for s in segments])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "least populated class has only N members"
        try:
            splitter = StratifiedGroupKFold(min(k, n_logs), shuffle=True, random_state=0)
            folds = list(splitter.split(logs, labels, groups=logs))
        except ValueError:  # every terrain has fewer segments than folds: whole logs, unstratified
            folds = list(GroupKFold(min(k, n_logs)).split(logs, groups=logs))
    if any(len({segments[i][3] for i in tr}) < 2 for tr, _ in folds):
        return []
    return folds


def fit_window_classifier(
    features: Sequence[SpectralSteps],
    segments: Sequence[Segment],
    classes: Sequence[str],
    *,
    config: WindowFitConfig | None = None,
    stretches: Sequence[Stretch] = (),
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ClassifierFit:
    """Fit the k fold models on labelled segments (and unlabelled stretches, with self-training).

    Args:
        features: Per log, its per-step spectral frames.
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        classes: The ``K`` class names.
        config: Fit settings.
        stretches: Unlabelled spans ``(log index, start, stop)`` for self-training (ignored when it is off).
        progress: Called after each fold.
        cancel: Polled between fits.

    Returns:
        The ensemble and out-of-fold metrics over every labelled step, each predicted by the fold model that did
        not train on it. ``metrics["pseudo_stretches"]`` is the mean number of stretches a fold took as
        pseudo-labels. ``metrics["held_out_logs"]`` (when two or more logs are labelled) is the honest figure: each
        labelled step predicted by a model fitted without any label or stretch of its log, from folds over logs
        (extra fits, not ensemble members).
    """
    if not segments:
        raise ValueError("no labelled segments to train the classifier on")
    config = config or WindowFitConfig()
    k = len(classes)
    t0 = time.monotonic()
    mean, std = _moments(features)
    window = features[0].config.window
    model_config = WindowClassifierConfig(features[0].shape[1], k, window=window, hidden=config.hidden)
    seg_rows = [frame_rows(features[i], a, b) for i, a, b, _ in segments]
    seg_y = [np.full(len(r), s[3]) for r, s in zip(seg_rows, segments, strict=True)]
    use_stretches = config.self_training and len(stretches) > 0
    # consecutive frames' windows share all but one frame: every PSEUDO_STRIDE-th row of a stretch carries nearly
    # all it holds, and the refits (most of a fit's time) read a third of the rows
    stretch_rows = [frame_rows(features[i], a, b)[::PSEUDO_STRIDE] for i, a, b in stretches] if use_stretches else []

    def fit_on(train_idx: np.ndarray, skip_logs: set[int], seed: int) -> tuple[WindowClassifier, int]:
        """A fold's network on its segments, trained again with the stretches of logs outside ``skip_logs``."""

        def fresh() -> WindowClassifier:
            torch.manual_seed(seed)
            model = WindowClassifier(model_config)
            model.set_standardisation(mean, std)
            return model

        x = np.concatenate([seg_rows[i] for i in train_idx])
        y = np.concatenate([seg_y[i] for i in train_idx])
        model = train_rows(fresh(), x, y, config.epochs, config, seed, cancel)
        rows = [r for r, s in zip(stretch_rows, stretches, strict=False) if s[0] not in skip_logs]
        px, py = _pseudo_labels(model, rows, config.agree) if use_stretches else ([], [])
        if px:
            x, y = np.concatenate([x, *px]), np.concatenate([y, *py])
            model = train_rows(fresh(), x, y, config.refit_epochs, config, seed, cancel)
        return model, len(px)

    def predict(val_idx: np.ndarray, model: WindowClassifier) -> tuple[np.ndarray, np.ndarray]:
        """Truth and prediction at every step of the segments ``val_idx``, as the passes score them."""
        true = [np.full(segments[i][2] - segments[i][1], segments[i][3]) for i in val_idx]
        pred = [predict_steps(model, features[segments[i][0]], segments[i][1], segments[i][2]) for i in val_idx]
        return np.concatenate(true), np.concatenate(pred)

    folds = fold_indices([s[3] for s in segments], config.k_folds, config.seed)
    by_log = _log_folds(segments, config.k_folds) if config.held_out else []
    models, histories, oof_true, oof_pred, pseudo = [], [], [], [], []
    for f_i, (train_idx, val_idx) in enumerate(folds, start=1):
        if cancel():
            raise Cancelled("classifier training cancelled")
        model, taken = fit_on(train_idx, set(), config.seed + f_i)
        pseudo.append(taken)
        models.append(model)
        true, pred = predict(val_idx, model)
        oof_true.append(true)
        oof_pred.append(pred)
        histories.append(
            [{"epoch": config.epochs, "pseudo_stretches": taken, "val_accuracy": float((true == pred).mean())}]
        )
        if progress:
            done = len(folds) + len(by_log)
            progress(Progress("classifier", f_i, done, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))
    metrics = classification_metrics(np.concatenate(oof_true), np.concatenate(oof_pred), classes)
    metrics["out_of_fold"] = len(folds) > 1
    metrics["n_segments"] = len(segments)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    metrics["pseudo_stretches"] = float(np.mean(pseudo))
    if by_log:
        held_true, held_pred = [], []
        for f_i, (train_idx, val_idx) in enumerate(by_log, start=len(folds) + 1):
            if cancel():
                raise Cancelled("classifier training cancelled")
            held = {segments[i][0] for i in val_idx}
            model, _ = fit_on(train_idx, held, config.seed + f_i)  # a held-out log lends no stretch: unseen
            true, pred = predict(val_idx, model)
            held_true.append(true)
            held_pred.append(pred)
            if progress:
                total = len(folds) + len(by_log)
                progress(Progress("classifier", f_i, total, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))
        m = classification_metrics(np.concatenate(held_true), np.concatenate(held_pred), classes)
        metrics["held_out_logs"] = {
            "accuracy": m["accuracy"],
            "macro_f1": m["macro_f1"],
            "per_class_recall": m["per_class_recall"],
            "folds": len(by_log),
            "logs": len({s[0] for s in segments}),
            "n": m["n"],
        }
    return ClassifierFit(models, metrics, histories, [v.tolist() for _, v in folds])  # type: ignore[arg-type]
