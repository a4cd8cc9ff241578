"""Stage 2 of the default family: the window classifier from labelled segments and, by self-training, from
unlabelled stretches too; a k-fold ensemble with out-of-fold metrics, as the paper family's stage 2.

Each fold is a multinomial logistic regression (scikit-learn's, L2 or elastic-net penalty) on the frame rows of its
segments: a step's input changes only when a frame completes, so one row per frame is the whole training set, with
no repeats. The regularisation is chosen once per fit by inner folds grouped by segment over the labelled rows.

Self-training, a fixed rule measured on BorealTC (``benchmarks/spectral_baseline.py``; +3 to +4 points at 10 % of
labels): each fold model labels every unlabelled stretch (a span with no change point and no label); a stretch whose
frames agree on one terrain (``agree`` of them) lends it to all of its frames, and the fold is fitted again on its
labels and these pseudo-labels. Its out-of-fold figures stay honest: stretches never hold a labelled step.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold

from .fit_classifier import ClassifierFit, Segment, fold_indices
from .metrics import classification_metrics
from .progress import CancelFn, Cancelled, Progress, ProgressFn, never
from .spectral import SpectralSteps
from .window_classifier import WindowClassifier, WindowClassifierConfig

PSEUDO_STRIDE = 3  # rows of a stretch self-training reads: every third frame
Stretch = tuple[int, int, int]  # (log index, start, stop): unlabelled, no change point inside


@dataclass(frozen=True)
class WindowFitConfig:
    """How the window classifier is fitted.

    Attributes:
        k_folds: Folds over segments; the fold models form the ensemble.
        c_grid: Inverse regularisation strengths the inner folds choose from.
        inner_folds: Inner folds (grouped by segment) that choose ``C``.
        l1_ratio: 0 is the L2 penalty (L-BFGS); above 0 the elastic net ``l1_ratio·|w| + (1 − l1_ratio)·w²`` of the
            paper's losses (SAGA, slower).
        self_training: Refit each fold with pseudo-labelled stretches.
        agree: Share of a stretch's frames that must agree before it is pseudo-labelled.
        max_iter: Solver iterations.
        held_out: Also measure accuracy on held-out logs (folds over logs: as many fits again).
        seed: Seed of the folds and solvers.
    """

    k_folds: int = 5
    c_grid: tuple[float, ...] = (0.01, 0.1, 1.0, 10.0)
    inner_folds: int = 3
    l1_ratio: float = 0.0
    self_training: bool = True
    agree: float = 0.9
    max_iter: int = 1000
    held_out: bool = True
    seed: int = 0


def _rows(features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """The distinct inputs of steps ``[start, stop)``: one per completed frame (the last step when none)."""
    steps = features.frame_rows(start, stop)
    if len(steps) == 0 and stop - 1 >= features.config.frame - 1:
        steps = np.asarray([stop - 1])
    if len(steps) == 0:
        return np.zeros((0, features.shape[1]), np.float32)
    block = features[int(steps[0]) : int(steps[-1]) + 1]
    return block[steps - steps[0]]


def _moments(features: Sequence[SpectralSteps]) -> tuple[np.ndarray, np.ndarray]:
    """Per-input mean and spread over every frame of every log (each frame stands for ``hop`` steps alike), summed
    a log at a time: a fleet's summaries never sit in memory together."""
    n, total, total_sq = 0, 0.0, 0.0
    for f in features:
        rows = np.asarray(f.summaries, np.float64)  # (N, 2F) of one log
        n += len(rows)
        total = total + rows.sum(0)
        total_sq = total_sq + np.square(rows).sum(0)
    mean = total / max(n, 1)
    std = np.sqrt(np.maximum(total_sq / max(n, 1) - np.square(mean), 0.0))
    return np.asarray(mean, np.float32), np.asarray(std, np.float32)


def _learner(c: float, config: WindowFitConfig) -> LogisticRegression:
    if config.l1_ratio > 0:
        return LogisticRegression(
            C=c, penalty="elasticnet", l1_ratio=config.l1_ratio, solver="saga", max_iter=config.max_iter, tol=1e-3
        )
    return LogisticRegression(C=c, max_iter=config.max_iter)


def _fit_linear(
    x: np.ndarray, y: np.ndarray, c: float, n_classes: int, config: WindowFitConfig
) -> tuple[np.ndarray, np.ndarray]:
    """``(K, F)`` weights and ``(K,)`` bias over all ``n_classes``; a class absent from ``y`` never wins."""
    present = np.unique(y)
    w = np.zeros((n_classes, x.shape[1]), np.float32)
    b = np.full(n_classes, -30.0, np.float32)
    if len(present) == 1:
        b[present[0]] = 30.0
        return w, b
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model = _learner(c, config).fit(x, y)
    if len(model.classes_) == 2:  # scikit-learn keeps one row for two classes: the second's logit over the first's
        w[model.classes_[0]], b[model.classes_[0]] = 0.0, 0.0
        w[model.classes_[1]], b[model.classes_[1]] = model.coef_[0], model.intercept_[0]
    else:
        w[model.classes_] = model.coef_
        b[model.classes_] = model.intercept_
    return w, b


def _choose_c(x: np.ndarray, y: np.ndarray, groups: np.ndarray, n_classes: int, config: WindowFitConfig) -> float:
    """The ``C`` of ``config.c_grid`` with the best accuracy over inner folds grouped by segment."""
    n_inner = min(config.inner_folds, len(np.unique(groups)))
    if n_inner < 2 or len(config.c_grid) == 1:
        return config.c_grid[len(config.c_grid) // 2]
    best, choice = -1.0, config.c_grid[0]
    for c in config.c_grid:
        hits = 0
        for tr, va in GroupKFold(n_inner).split(x, y, groups):
            w, b = _fit_linear(x[tr], y[tr], c, n_classes, config)
            hits += int(((x[va] @ w.T + b).argmax(1) == y[va]).sum())
        if hits > best:
            best, choice = hits, c
    return choice


def _pseudo_labels(
    w: np.ndarray, b: np.ndarray, stretch_rows: Sequence[np.ndarray], agree: float
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    xs, ys = [], []
    for rows in stretch_rows:
        if len(rows) == 0:
            continue
        guess = (rows @ w.T + b).argmax(1)
        counts = np.bincount(guess, minlength=len(b))
        if counts.max() >= agree * len(guess):
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
        features: Per log, its per-step spectral summaries.
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        classes: The ``K`` class names.
        config: Fit settings.
        stretches: Unlabelled spans ``(log index, start, stop)`` for self-training (ignored when it is off).
        progress: Called after each fold.
        cancel: Polled between fits.

    Returns:
        The ensemble and out-of-fold metrics over every labelled step, each predicted by the fold model that did
        not train on it. ``metrics["c"]`` is the chosen regularisation, ``metrics["pseudo_stretches"]`` the mean
        number of stretches a fold took as pseudo-labels. ``metrics["held_out_logs"]`` (when two or more logs are
        labelled) is the honest figure: each labelled step predicted by a model fitted without any label or
        stretch of its log, from folds over logs (extra fits, not ensemble members).
    """
    if not segments:
        raise ValueError("no labelled segments to train the classifier on")
    config = config or WindowFitConfig()
    k = len(classes)
    t0 = time.monotonic()
    mean, std = _moments(features)
    std = np.where(std > 1e-8, std, 1.0).astype(np.float32)

    def standard(a: np.ndarray) -> np.ndarray:
        return (a - mean) / std

    seg_rows = [standard(_rows(features[i], a, b)) for i, a, b, _ in segments]
    seg_y = [np.full(len(r), s[3]) for r, s in zip(seg_rows, segments, strict=True)]
    use_stretches = config.self_training and len(stretches) > 0
    # consecutive frames' summaries share all but one frame: every PSEUDO_STRIDE-th row of a stretch carries nearly
    # all it holds, and the refits (most of a fit's time) read a third of the rows
    stretch_rows = (
        [standard(_rows(features[i], a, b))[::PSEUDO_STRIDE] for i, a, b in stretches] if use_stretches else []
    )
    x_all, y_all = np.concatenate(seg_rows), np.concatenate(seg_y)
    groups = np.concatenate([np.full(len(r), j) for j, r in enumerate(seg_rows)])
    c = _choose_c(x_all, y_all, groups, k, config)

    def fit_on(train_idx: np.ndarray, skip_logs: set[int]) -> tuple[np.ndarray, np.ndarray, int]:
        """A fold's linear model on its segments, refitted with the stretches of logs outside ``skip_logs``."""
        x = np.concatenate([seg_rows[i] for i in train_idx])
        y = np.concatenate([seg_y[i] for i in train_idx])
        w, b = _fit_linear(x, y, c, k, config)
        rows = [r for r, s in zip(stretch_rows, stretches, strict=False) if s[0] not in skip_logs]
        px, py = _pseudo_labels(w, b, rows, config.agree) if use_stretches else ([], [])
        if px:
            w, b = _fit_linear(np.concatenate([x, *px]), np.concatenate([y, *py]), c, k, config)
        return w, b, len(px)

    def predict(val_idx: np.ndarray, w: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Truth and prediction at every step of the segments ``val_idx``, as the passes score them."""
        true, pred = [], []
        for i in val_idx:
            seq, a, stop, label = segments[i]
            true.append(np.full(stop - a, label))
            pred.append((standard(features[seq][a:stop]) @ w.T + b).argmax(1))
        return np.concatenate(true), np.concatenate(pred)

    folds = fold_indices([s[3] for s in segments], config.k_folds, config.seed)
    by_log = _log_folds(segments, config.k_folds) if config.held_out else []
    models, histories, oof_true, oof_pred, pseudo = [], [], [], [], []
    for f_i, (train_idx, val_idx) in enumerate(folds, start=1):
        if cancel():
            raise Cancelled("classifier training cancelled")
        w, b, taken = fit_on(train_idx, set())
        pseudo.append(taken)
        model = WindowClassifier(WindowClassifierConfig(features[0].shape[1], k))
        model.set_standardisation(mean, std)
        model.set_linear(w, b)
        models.append(model.eval())
        true, pred = predict(val_idx, w, b)
        oof_true.append(true)
        oof_pred.append(pred)
        histories.append(
            [{"epoch": 1, "c": c, "pseudo_stretches": taken, "val_accuracy": float((true == pred).mean())}]
        )
        if progress:
            done = len(folds) + len(by_log)
            progress(Progress("classifier", f_i, done, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))
    metrics = classification_metrics(np.concatenate(oof_true), np.concatenate(oof_pred), classes)
    metrics["out_of_fold"] = len(folds) > 1
    metrics["n_segments"] = len(segments)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    metrics["c"] = c
    metrics["pseudo_stretches"] = float(np.mean(pseudo))
    if by_log:
        held_true, held_pred = [], []
        for f_i, (train_idx, val_idx) in enumerate(by_log, start=len(folds) + 1):
            if cancel():
                raise Cancelled("classifier training cancelled")
            held = {segments[i][0] for i in val_idx}
            w, b, _ = fit_on(train_idx, held)  # a held-out log lends no stretch either: it stays unseen
            true, pred = predict(val_idx, w, b)
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
