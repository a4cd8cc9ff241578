"""The MiniRocket family's stage 2 in a session: one transform for every log, a ridge head per blocked fold, the
same out-of-fold and held-out-log figures as the default family's fit, and one temperature for the ensemble.

The transform's biases come from windows of every log, drawn without reading a label (as the default family's
stage 1 reads every log); only the heads read labels. The head is closed-form, so a fold costs its transform of
the labelled windows (computed once for every fold) and a ridge solve: no epochs, no self-training.

The heads read at most :data:`ROWS` labelled hop rows, a draw of each terrain's rows in proportion: a ridge solve
over ``n`` rows of 9,996 features costs ``n²`` in time and memory, so every label read took 588 s and 4.3 GB on a
10.1 h session at 5 % labelled (9,090 rows); past the budget the rows are overlapping windows of the same stretches.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from ..figures import blocked_folds, classification_metrics, log_folds, terrain_estimate
from ..fitting import ClassifierFit, Segment
from ..running import CancelFn, Cancelled, Progress, ProgressFn, never
from ..spectral_cnn import WindowFitConfig
from .raw_steps import RawSteps
from .rocket_classifier import RocketClassifier
from .rocket_fit import (
    feature_scale,
    fit_temperature_nll,
    ridge_head,
    rocket_features,
    rocket_model,
)
from .rocket_kernels import fit_rocket, on_grid

POOL = 2000  # windows of all logs the transform's biases are drawn from
ROWS = 4096  # labelled hop rows the heads read at most (BorealTC's runs at 10 %: 2,334, all read)
FLOOR = 64  # each terrain keeps this many of its rows at least (all, when it has fewer), whatever its share
FEATURES = 9_996  # aeon's default (10,000 rounded down to a multiple of 84)
BLOCK_GUARDS = 4  # a blocked fold's block is this many guards long, as the default family's


class _Rows:
    """Every labelled hop row's features, computed once: per log its steps (ascending), features and terrain."""

    def __init__(
        self,
        features: Sequence[RawSteps],
        segments: Sequence[Segment],
        model: RocketClassifier,
        *,
        budget: int,
        seed: int,
    ) -> None:
        by_log: dict[int, dict[int, int]] = {}
        for log, a, b, c in segments:
            steps = features[log].hop_rows(a, b)
            if len(steps) == 0 and b > a:  # a segment shorter than a hop: its last step
                steps = np.asarray([b - 1])
            by_log.setdefault(log, {}).update(dict.fromkeys(steps.tolist(), c))
        total = sum(len(v) for v in by_log.values())
        by_log = _within_budget(by_log, budget, seed)
        self.read = (sum(len(v) for v in by_log.values()), total)  # the rows the heads read, of the labelled ones
        self.steps, self.x, self.y = {}, {}, {}
        for log, label_of in by_log.items():
            steps = np.asarray(sorted(label_of), np.int64)
            windows = features[log].at(steps).reshape(len(steps), features[log].length, features[log].channels)
            self.steps[log] = steps
            self.x[log] = rocket_features(model, windows)  # (N, F)
            self.y[log] = np.asarray([label_of[s] for s in steps.tolist()], np.int64)

    def of(self, segments: Sequence[Segment]) -> tuple[np.ndarray, np.ndarray]:
        """The features and terrains of the hop rows inside ``segments``."""
        xs, ys = [], []
        for log, a, b, _ in segments:
            steps = self.steps.get(log)
            if steps is None:
                continue
            lo, hi = np.searchsorted(steps, a), np.searchsorted(steps, b)  # a piece the guards cut short may have none
            xs.append(self.x[log][lo:hi])
            ys.append(self.y[log][lo:hi])
        if not xs:
            return np.zeros((0, 0), np.float32), np.zeros(0, np.int64)
        return np.concatenate(xs), np.concatenate(ys)


def _within_budget(by_log: dict[int, dict[int, int]], budget: int, seed: int) -> dict[int, dict[int, int]]:
    """``by_log`` (per log, each labelled hop row's terrain) with at most about ``budget`` rows: each terrain keeps a
    uniform draw of its rows in proportion to its share (at least :data:`FLOOR`, or all it has); as is when under."""
    where = [(log, step, c) for log in sorted(by_log) for step, c in sorted(by_log[log].items())]
    if len(where) <= budget:
        return by_log
    terrain = np.asarray([c for _, _, c in where])
    rng = np.random.default_rng((seed, len(where)))
    kept = []
    for c in np.unique(terrain):
        mine = np.flatnonzero(terrain == c)
        quota = min(len(mine), max(FLOOR, round(len(mine) * budget / len(where))))
        kept.append(rng.choice(mine, quota, replace=False))
    out: dict[int, dict[int, int]] = {}
    for i in np.sort(np.concatenate(kept)).tolist():
        log, step, c = where[i]
        out.setdefault(log, {})[step] = c
    return out


def _pool(features: Sequence[RawSteps], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` windows ``(n, C, L)`` at random hops of every log, in proportion to their length (no label read)."""
    hops = np.asarray([max(len(f) // f.hop, 1) for f in features], np.float64)
    which = rng.choice(len(features), size=n, p=hops / hops.sum())
    out = []
    for log in np.unique(which):
        f = features[log]
        first = min(f.length - 1, len(f) - 1)  # a window that starts inside the log, where there is one
        steps = np.sort(rng.integers(first, len(f), size=int((which == log).sum())))
        out.append(f.at(steps).reshape(len(steps), f.length, f.channels))
    return on_grid(np.concatenate(out)).transpose(0, 2, 1)  # the biases from windows as the classifier sees them


def _head(x: np.ndarray, y: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    scale = feature_scale(x)
    w, b, _ = ridge_head(x * scale, y, k)
    return scale, w, b


def _scores(head: tuple[np.ndarray, np.ndarray, np.ndarray], x: np.ndarray) -> np.ndarray:
    scale, w, b = head
    return (x * scale) @ w.T + b  # (N, K)


def fit_rocket_steps(
    features: Sequence[RawSteps],
    segments: Sequence[Segment],
    classes: Sequence[str],
    *,
    config: WindowFitConfig | None = None,
    stretches: Sequence[tuple[int, int, int]] = (),
    groups: Sequence[int] | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ClassifierFit:
    """Fit the k fold models on labelled segments (``stretches`` are ignored: the family has no self-training).

    Args:
        features: Per log, its per-step windows (``RawSteps``).
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        classes: The ``K`` class names.
        config: Reads ``k_folds``, ``held_out``, ``calibrate`` and ``seed`` (the default family's fit settings).
        stretches: Unused.
        groups: The recording each log belongs to, for the held-out-log figures; default: every log its own.
        progress: Called after each fold.
        cancel: Polled between folds.

    Returns:
        As ``fit_window_classifier``: the ensemble, its blocked out-of-fold metrics, ``held_out_logs`` where a
        terrain is labelled in two logs or more, the ``estimate``, and one temperature (``metrics["calibration"]``)
        fitted on held-out-log scores where they exist, else on the blocked out-of-fold ones. No drift reference.

    Raises:
        ValueError: No labelled segment, or fewer than two terrains labelled.
    """
    if not segments:
        raise ValueError("no labelled segments to train the classifier on")
    if len({s[3] for s in segments}) < 2:
        raise ValueError("a MiniRocket classifier needs two terrains labelled or more")
    config = config or WindowFitConfig()
    t0, k = time.monotonic(), len(classes)
    f0 = features[0]
    rng = np.random.default_rng(config.seed)
    params = fit_rocket(_pool(features, POOL, rng), features=FEATURES, seed=config.seed)
    base = rocket_model(params, k, hop=f0.hop)
    rows = _Rows(features, segments, base, budget=ROWS, seed=config.seed)
    guard = f0.length + f0.hop
    blocked = blocked_folds(segments, config.k_folds, block=BLOCK_GUARDS * guard, guard=guard)
    pieces = [p.as_segment for p in blocked.pieces]
    group_of = list(range(len(features))) if groups is None else [int(g) for g in groups]
    logs_per_class = {c: len({group_of[s[0]] for s in segments if s[3] == c}) for c in {s[3] for s in segments}}
    shared = any(n >= 2 for n in logs_per_class.values())
    by_log = log_folds(segments, config.k_folds, group_of) if config.held_out and shared else []
    total = blocked.k + len(by_log)

    def step(done: int) -> None:
        if cancel():
            raise Cancelled("training was cancelled")
        if progress:
            progress(Progress("classifier", done, total, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))

    heads, oof_scores, oof_true = [], [], []
    for f in range(blocked.k):
        train = blocked.training(f) if blocked.k > 1 else pieces
        x, y = rows.of(train)
        if len(np.unique(y)) < 2:  # the guards left one terrain: this fold trains on every piece
            x, y = rows.of(pieces)
        heads.append(_head(x, y, k))
        if blocked.k > 1:
            hx, hy = rows.of([pieces[j] for j in blocked.held_out(f)])
            seen = np.isin(hy, np.unique(y))  # a terrain this fold never trained on cannot be right
            oof_scores.append(_scores(heads[-1], hx[seen]))
            oof_true.append(hy[seen])
        step(f + 1)
    metrics: dict = {}
    calibration = (np.zeros((0, k)), np.zeros(0, np.int64), "same run")
    if oof_true:
        same_scores, same_true = np.concatenate(oof_scores), np.concatenate(oof_true)
        metrics = classification_metrics(same_true, same_scores.argmax(1), classes)
        calibration = (same_scores, same_true, "same run")
    else:
        metrics = classification_metrics(np.zeros(0), np.zeros(0), classes)
    metrics["out_of_fold"] = blocked.k > 1
    metrics["n_segments"] = len(segments)
    metrics["n_pieces"] = len(pieces)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    metrics["pseudo_stretches"] = 0.0
    metrics["rows_read"] = list(rows.read)
    held_out = None
    if by_log:
        h_scores, h_true = [], []
        for i, (tr, va) in enumerate(by_log, start=blocked.k + 1):
            x, y = rows.of([segments[j] for j in tr])
            hx, hy = rows.of([segments[j] for j in va])
            measurable = [c for c in np.unique(y) if logs_per_class[int(c)] >= 2]
            keep = np.isin(hy, measurable)
            h_scores.append(_scores(_head(x, y, k), hx[keep]))
            h_true.append(hy[keep])
            step(i)
        scores, truth = np.concatenate(h_scores), np.concatenate(h_true)
        if len(truth):
            held_out = truth, scores.argmax(1)
            m = classification_metrics(*held_out, classes)
            metrics["held_out_logs"] = {
                "accuracy": m["accuracy"],
                "macro_f1": m["macro_f1"],
                "per_class_recall": m["per_class_recall"],
                "folds": len(by_log),
                "logs": len({s[0] for s in segments}),
                "n": m["n"],
            }
            calibration = (scores, truth, "held-out logs")
    if blocked.k > 1 and oof_true:
        metrics["estimate"] = terrain_estimate(classes, logs_per_class, (same_true, same_scores.argmax(1)), held_out)
    scores, truth, source = calibration
    temperature = fit_temperature_nll(scores, truth) if config.calibrate and len(truth) else 1.0
    metrics["calibration"] = {"temperature": temperature, "on": source, "n": len(truth)}
    models = [rocket_model(params, k, hop=f0.hop, head=(*h, temperature)) for h in heads]
    history = [[{"epoch": 0, "pseudo_stretches": 0}] for _ in models]
    return ClassifierFit(
        models, metrics, history, [blocked.held_out(f) for f in range(blocked.k)],
        [(p.segment, p.start, p.stop) for p in blocked.pieces],
    )  # fmt: skip
