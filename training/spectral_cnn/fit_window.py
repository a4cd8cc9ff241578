"""Stage 2 of the default family: the window classifier from labelled segments and, by self-training, from
unlabelled stretches too; a k-fold ensemble with out-of-fold metrics, as the paper family's stage 2.

Each fold is a small network (:class:`.window_classifier.WindowClassifier`) trained with AdamW on the frame
rows of its segments: a step's input changes only when a frame completes, so one row per frame is the whole training
set, with no repeats. Weight decay, dropout and input noise regularise it; the settings were chosen on BorealTC's
inner folds (``benchmarks/studies/default_family_cnn.py``), never on its test folds.

Self-training, a fixed rule measured on BorealTC at 10 % of labels (+1.6 points on the authors' folds and +0.5 on
unseen runs for the network; ``benchmarks/studies/default_family_ablation.py``): each fold model labels every unlabelled
stretch (a span with no change point and no label); a stretch whose frames agree on one terrain (``agree`` of them)
lends it to all of its frames, and the fold's network goes on training on its labels and these pseudo-labels
(``refit_epochs``). Its out-of-fold figures stay honest: stretches never hold a labelled step.

The refit goes on from the network that labelled the stretches, for 10 passes, rather than training a new one for
30: a first model on 11 quadruped-shaped logs of 50 Hz IMU
(``benchmarks/speed/bench_first_model.py``) trained its stage 2 in 36 s instead of 70, and BorealTC's folds by run
at 10 % of labels (two seeds, checked once, not screened) scored 81.8 % against 81.3 %.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path

import numpy as np
import torch

from ..figures import blocked_folds, classification_metrics, log_folds, terrain_estimate, unseen_runs_figure
from ..fitting import ClassifierFit, Segment
from ..running import INIT_LOCK, CancelFn, Progress, ProgressFn, fit_workers, never, run_fits
from .fit_starts import load_start, save_start, start_key
from .spectra import SpectralConfig, SpectralSteps, frame_moments
from .stretch_pool import PSEUDO_STRIDE, Stretch, every_row, pool_draw, stretch_pool
from .window_calibration import fit_temperature, scale_head
from .window_classifier import WindowClassifier, WindowClassifierConfig
from .window_config import WindowFitConfig
from .window_drift import fit_drift, held_out_relation
from .window_rows import WindowRows, at_most, window_rows
from .window_train import train_rows

BLOCK_GUARDS = 4  # a block is four guards long: a fold's guard never takes more than half of a block next to it
HELD_ROWS = 8192  # a member's held-out rows the drift reads: a sample past it (100 hours at 5 %: 18,000 each)
PREDICT_CHUNK = 4096  # steps per call when scoring segments: bounds the stacked frames in memory


def block_and_guard(front: SpectralConfig) -> tuple[int, int]:
    """Samples per block of the ensemble's blocked folds, and the guard around a held-out block: wider than the
    input a step reads (its last ``window`` frames)."""
    guard = front.span + front.hop
    return BLOCK_GUARDS * guard, guard


@torch.inference_mode()
def predict_steps(model: WindowClassifier, features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """Classes of steps ``[start, stop)`` of one log, as the offline passes score them (a chunk at a time)."""
    out, dev = [], model.in_mean.device
    for c in range(start, stop, PREDICT_CHUNK):
        chunk = torch.from_numpy(features[c : min(c + PREDICT_CHUNK, stop)])[None].to(dev)  # (1, L, D)
        out.append(model(chunk)[0][0].argmax(1).cpu().numpy())
    features.release()
    return np.concatenate(out) if out else np.zeros(0, np.int64)


@torch.inference_mode()
def row_logits(model: WindowClassifier, x: np.ndarray | WindowRows) -> np.ndarray:
    """Logits ``(N, K)`` of rows ``(N, W·F)`` (stacked, or :class:`WindowRows` stacked a chunk at a time)."""
    if len(x) == 0:
        return np.zeros((0, model.config.n_classes), np.float32)
    n, big = divmod(len(x), -(-len(x) // PREDICT_CHUNK))  # np.array_split's chunks: ``big`` one row longer
    cuts = np.concatenate([[0], np.cumsum([n + 1] * big + [n] * (-(-len(x) // PREDICT_CHUNK) - big))])
    chunks = (np.asarray(x[a:b], np.float32) for a, b in itertools.pairwise(cuts))
    dev = model.in_mean.device
    return torch.cat([model.logits(torch.from_numpy(c).to(dev)).cpu() for c in chunks]).numpy()


def _predict_rows(model: WindowClassifier, x: np.ndarray) -> np.ndarray:
    """Classes of rows ``(N, W·F)``."""
    return row_logits(model, x).argmax(1)


def _pseudo_labels(
    model: WindowClassifier,
    pool: np.ndarray,
    bounds: np.ndarray,
    stretches: Sequence[int],
    agree: float,
    *,
    units: np.ndarray | None = None,
    unit_agree: float = 0.0,
    taught: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """The pool rows of the ``stretches`` (indices into ``bounds``) whose rows agree on a class, that class per row,
    and how many stretches were taken. With ``units`` (one id per stretch in ``bounds``) and ``unit_agree``, the
    stretches of a unit whose rows together agree (``unit_agree`` of them) all take the unit's class, whatever
    each says alone; the others are judged alone. With ``taught`` (one class per stretch in ``bounds``, ``-1``:
    none), a stretch the session teaches takes that class, whatever the model says of it."""
    k = model.config.n_classes
    counts: dict[int, np.ndarray] = {}  # per stretch with rows, its rows' predicted classes counted
    for j in stretches:
        a, b = int(bounds[j]), int(bounds[j + 1])
        if b > a and taught is not None and taught[j] >= 0:
            counts[j] = np.bincount([int(taught[j])], minlength=k) * (b - a)  # sure by the session's word
        elif b > a:
            counts[j] = np.bincount(_predict_rows(model, pool[a:b]), minlength=k)
    by_unit: dict[int, np.ndarray] = {}  # the same, summed over each unit's stretches
    if units is not None and unit_agree > 0:
        for j, c in counts.items():
            u = int(units[j])
            by_unit[u] = by_unit[u] + c if u in by_unit else c
    index, ys, taken = [], [], 0
    for j, c in counts.items():
        a, b = int(bounds[j]), int(bounds[j + 1])
        joint = by_unit.get(int(units[j])) if units is not None and by_unit else None
        if joint is not None and joint.max() >= unit_agree * joint.sum():
            label = joint.argmax()
        elif c.max() >= agree * (b - a):
            label = c.argmax()
        else:
            continue
        index.append(np.arange(a, b))
        ys.append(np.full(b - a, label))
        taken += 1
    if not index:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), 0
    return np.concatenate(index), np.concatenate(ys), taken


def fit_window_classifier(
    features: Sequence[SpectralSteps],
    segments: Sequence[Segment],
    classes: Sequence[str],
    *,
    config: WindowFitConfig | None = None,
    stretches: Sequence[Stretch] = (),
    units: Sequence[int] | None = None,
    taught: Sequence[int] | None = None,
    known: Sequence[int] | None = None,
    groups: Sequence[int] | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    workers: int | None = None,
    device: str = "cpu",
    starts: Path | None = None,
) -> ClassifierFit:
    """Fit the k fold models on labelled segments (and unlabelled stretches, with self-training).

    Args:
        features: Per log, its per-step spectral frames.
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        classes: The ``K`` class names.
        config: Fit settings.
        stretches: Unlabelled spans ``(log index, start, stop)`` for self-training (ignored when it is off).
        units: Per stretch, the longer span it is a piece of (no change point or label between them):
            ``config.unit_agree`` judges the pieces of a unit together. Default: each stretch its own.
        taught: Per stretch, the class the session teaches there (``labeling.taught_terrains``: its blend of the
            ensemble and the runs' label votes, where sure), ``-1`` where it teaches none: such a stretch takes that
            class instead of the fold model's own agreement. Default: none taught.
        known: Per stretch, the terrain the session knows there (its scores sure of one, ``-1``: not known): the
            folds over logs score their held-out runs on it beside their labels, ``metrics["unseen_runs"]``.
        groups: The recording (run) each log belongs to, for the held-out figures and the calibration; default:
            every log is its own (a session's logs are runs; a protocol that cuts runs into pieces passes the runs).
        progress: Called after each fit, on the calling thread.
        cancel: Polled between epochs.
        workers: Fits run side by side (in forked processes on Linux, :mod:`training.running.fit_processes`, else in
            threads); default: one per torch thread. The result does not depend on it.
        device: Where the networks train and score their held-out rows (``"cuda"``: on the GPU, their batches still
            gathered on the CPU); the models come back on the CPU either way.
        starts: A folder where each network trained on the labels alone is kept (:mod:`.fit_starts`): a later fit
            whose network would be the same (its rows, classes, seed, settings) reads it instead of training it,
            with the same result. Default: none kept.

    Returns:
        The ensemble (one model per blocked fold, :mod:`training.figures.blocking`) and its out-of-fold metrics: each
        labelled step predicted by the fold model that did not train on its block, steps of a terrain that model
        never saw left out (same-run figures). ``metrics["pseudo_stretches"]`` is the mean number of stretches a
        fold took as pseudo-labels. ``metrics["held_out_logs"]`` (when a terrain is labelled in two logs or more):
        its steps predicted by a model fitted without any label or stretch of their log, from folds over logs
        (extra fits, not ensemble members). ``metrics["estimate"]``
        (:func:`training.figures.estimates.terrain_estimate`) says per terrain which of the two exists.
        ``metrics["unseen_runs"]`` (:func:`training.figures.unseen_runs.unseen_runs_figure`): the same folds' models
        on their held-out runs' labels and ``known`` stretches, per run, with a 90 % interval over runs: what the
        model that ships is expected to score on a run it never saw. ``folds``
        index ``pieces``: the segments cut into blocks. The members' logits are divided by one temperature (folded
        into their heads) fitted on held-out-log predictions where they exist, else on the blocked out-of-fold ones
        (``metrics["calibration"]``); ``drift`` is the ensemble's :class:`.window_drift.DriftReference`.
    """
    if not segments:
        raise ValueError("no labelled segments to train the classifier on")
    config = config or WindowFitConfig()
    k = len(classes)
    t0 = time.monotonic()
    mean, std = frame_moments([f.frames for f in features])
    front = features[0].config
    model_config = WindowClassifierConfig(features[0].shape[1], k, window=front.window, hidden=config.hidden)
    use_stretches = config.self_training and len(stretches) > 0
    # consecutive frames' windows share all but one frame: every PSEUDO_STRIDE-th row of a stretch carries nearly
    # all it holds, and the refits (most of a fit's time) read a third of the rows
    # past config.pool_mib (a fleet's hours) a draw of the stretches: memory stays flat with the hours
    used = stretches if use_stretches else []
    keep = pool_draw(features, used, budget_mib=config.pool_mib, share=config.pool_share, seed=config.seed)
    pool, bounds = stretch_pool(features, used, PSEUDO_STRIDE, keep=keep)
    unit_of = None if units is None else np.asarray(units, np.int64)
    taught_of = None if taught is None else np.asarray(taught, np.int64)
    known_of = np.full(len(stretches), -1, np.int64) if known is None else np.asarray(known, np.int64)

    def fit_on(
        train: Sequence[Segment], skip_logs: set[int], seed: int
    ) -> tuple[WindowClassifier, int, set[int], WindowRows]:
        """A fold's network on ``train``, trained again with the stretches of logs outside ``skip_logs``; with the
        classes it saw and the labelled rows it trained on."""

        def fresh() -> WindowClassifier:
            with INIT_LOCK:  # the initial weights come from torch's global generator
                torch.manual_seed(seed)
                model = WindowClassifier(model_config)
            model.set_standardisation(mean, std)
            return model.to(device)

        x, ends = window_rows(features, [s[:3] for s in train], every_row)  # each segment's frames held once
        if len(x) == 0:
            raise ValueError("the labelled segments are shorter than one frame: nothing to train the classifier on")
        labelled = x
        y = np.repeat(np.asarray([s[3] for s in train], np.int64), np.diff(ends))
        model = fresh()
        key = start_key(features, train, model, config, seed) if starts is not None else ""
        kept = load_start(starts, key, model) if key else None  # the same network, trained by an earlier fit
        if kept is None:
            model = train_rows(fresh() if key else model, x, y, config.epochs, config, seed, cancel, front=front)
            if key:
                save_start(starts, key, model)
        seen = {int(c) for c in np.unique(y)}
        kept = [j for j, s in enumerate(stretches) if s[0] not in skip_logs] if use_stretches else []
        index, py, taken = _pseudo_labels(
            model, pool, bounds, kept, config.agree, units=unit_of, unit_agree=config.unit_agree, taught=taught_of
        )
        if taken:  # the pseudo-labelled rows are read in the pool, not copied beside the labelled ones
            y = np.concatenate([y, py])
            start = model if config.warm_refit else fresh()  # train_rows puts it back in training mode
            model = train_rows(start, x, y, config.refit_epochs, config, seed, cancel, front=front, more=(pool, index))
        return model, taken, seen, labelled

    def predict(held: Sequence[Segment], model: WindowClassifier) -> tuple[np.ndarray, np.ndarray]:
        """Truth and prediction at every step of ``held``, as the passes score them."""
        true = [np.full(b - a, c) for _, a, b, c in held]
        pred = [predict_steps(model, features[i], a, b) for i, a, b, _ in held]
        return np.concatenate(true), np.concatenate(pred)

    def held_rows(held: Sequence[Segment], seen: set[int]) -> tuple[WindowRows, np.ndarray]:
        """The frame rows of ``held`` and their classes, terrains outside ``seen`` left out."""
        kept = [s for s in held if s[3] in seen]
        rows, ends = window_rows(features, [s[:3] for s in kept], every_row)
        return rows, np.repeat(np.asarray([s[3] for s in kept], np.int64), np.diff(ends))

    # the ensemble's folds hold out contiguous blocks, a guard wider than a step's input around them: labels given
    # as whole runs (one segment per terrain) still leave every fold every terrain
    block, guard = block_and_guard(front)
    blocked = blocked_folds(segments, config.k_folds, block=block, guard=guard)
    pieces = [p.as_segment for p in blocked.pieces]
    group_of = list(range(len(features))) if groups is None else [int(g) for g in groups]
    logs_per_class = {c: len({group_of[s[0]] for s in segments if s[3] == c}) for c in {s[3] for s in segments}}
    shared = any(n >= 2 for n in logs_per_class.values())  # a terrain in two logs: held-out logs can measure it
    by_log = log_folds(segments, config.k_folds, group_of) if config.held_out and shared else []
    total = blocked.k + len(by_log)

    def member(f: int) -> tuple:
        """Blocked fold ``f``'s model, the stretches it took, the classes it saw, the labelled rows the drift
        reference keeps (``config.reference_rows`` of those it trained on), its held-out block's logits and classes,
        which of those rows the drift's relation to accuracy reads (at most ``HELD_ROWS``) and those rows, and its
        steps' truth and prediction."""
        held = [pieces[j] for j in blocked.held_out(f)]
        train = blocked.training(f) if blocked.k > 1 else pieces
        if not any(b > a and b >= front.frame for _, a, b, _ in train):  # a piece has rows once it reaches a frame
            # tiny labels close together: the guards took every other piece; this one fold trains on them whole
            train = [pieces[j] for j, g in enumerate(blocked.fold_of) if g != f] or pieces
        model, taken, seen, labelled = fit_on(train, set(), config.seed + f + 1)
        pick = at_most(len(labelled), config.reference_rows, (config.seed, f))  # what the drift reference keeps of them
        rows, rows_y = held_rows(held, seen) if blocked.k > 1 else held_rows([], seen)
        logits = row_logits(model, rows)  # every held-out row: the calibration's
        some = at_most(len(rows), HELD_ROWS, (config.seed, f, 1))  # the drift's figures read a sample
        return model, taken, seen, labelled.take(pick), logits, rows_y, some, rows.take(some), *predict(held, model)

    def log_fit(f_i: int, train_idx: np.ndarray, val_idx: np.ndarray) -> tuple:
        """Truth, prediction, logits and classes of a fold over logs' held-out segments, by a model fitted without
        any label or stretch of their logs (not an ensemble member); and per held-out run, the time it named right
        and the time scored, over its labels and the stretches whose terrain the session knows."""
        held_groups = {group_of[segments[i][0]] for i in val_idx}
        held_logs = {j for j, g in enumerate(group_of) if g in held_groups}
        model, _, seen, _ = fit_on([segments[i] for i in train_idx], held_logs, config.seed + f_i)
        measurable = {c for c in seen if logs_per_class[c] >= 2}  # a one-log terrain has no other log to learn
        right: dict[int, float] = {}
        scored: dict[int, float] = {}
        trues, preds = [], []
        for i in val_idx:
            t, p = predict([segments[i]], model)
            trues.append(t)
            preds.append(p)
            if segments[i][3] in measurable:
                g = group_of[segments[i][0]]
                right[g] = right.get(g, 0.0) + float((t == p).sum())
                scored[g] = scored.get(g, 0.0) + float(len(t))
        for j, (i, a, b) in enumerate(stretches):  # every PSEUDO_STRIDE-th row: a stretch's share right, its time
            lo, hi = int(bounds[j]), int(bounds[j + 1])
            if i in held_logs and known_of[j] in measurable and hi > lo:
                share = float((_predict_rows(model, pool[lo:hi]) == known_of[j]).mean())
                right[group_of[i]] = right.get(group_of[i], 0.0) + share * (b - a)
                scored[group_of[i]] = scored.get(group_of[i], 0.0) + float(b - a)
        true, pred = np.concatenate(trues), np.concatenate(preds)
        keep = np.isin(true, list(measurable))
        rows, rows_y = held_rows([segments[i] for i in val_idx], measurable)
        return true[keep], pred[keep], row_logits(model, rows), rows_y, right, scored

    def reported(done: int) -> None:
        if progress:
            progress(Progress("classifier", done, total, 1, 1, 1, 1, 0.0, None, None, time.monotonic() - t0))

    jobs = [partial(member, f) for f in range(blocked.k)]
    jobs += [partial(log_fit, f_i, tr, va) for f_i, (tr, va) in enumerate(by_log, blocked.k + 1)]

    def pack(result: tuple) -> tuple:  # a member's network travels from a forked fit as its weights
        if result and isinstance(result[0], WindowClassifier):
            return ({k: v.numpy() for k, v in result[0].state_dict().items()}, *result[1:])
        return result

    def unpack(result: tuple) -> tuple:
        if result and isinstance(result[0], dict):
            model = WindowClassifier(model_config)
            model.load_state_dict({k: torch.from_numpy(v) for k, v in result[0].items()})
            return (model.eval(), *result[1:])
        return result

    results = run_fits(
        jobs,
        workers=fit_workers(total) if workers is None else workers,
        done=reported,
        portable=(pack, unpack) if torch.device(device).type == "cpu" else None,
        cancel=cancel,
    )
    models, histories, oof_true, oof_pred, pseudo = [], [], [], [], []
    trained_rows, oof_rows, oof_logits, oof_classes = [], [], [], []  # per member: for the drift and calibration
    right = []  # per member: whether it named each row of its drift sample right
    for model, taken, seen, labelled, logits, rows_y, some, rows, true, pred in results[: blocked.k]:
        pseudo.append(taken)
        models.append(model.cpu())  # the calibration, the drift and every caller read them on the CPU
        trained_rows.append(labelled)
        oof_rows.append(rows)
        oof_logits.append(logits)
        oof_classes.append(rows_y)
        right.append(logits[some].argmax(1) == rows_y[some])
        histories.append(
            [{"epoch": config.epochs, "pseudo_stretches": taken, "val_accuracy": float((true == pred).mean())}]
        )
        if blocked.k > 1:  # a terrain this fold never trained on cannot be right: its steps are not measured
            keep = np.isin(true, list(seen))
            true, pred = true[keep], pred[keep]
        oof_true.append(true)
        oof_pred.append(pred)
    same_true, same_pred = np.concatenate(oof_true), np.concatenate(oof_pred)
    metrics = classification_metrics(same_true, same_pred, classes)
    metrics["out_of_fold"] = blocked.k > 1
    metrics["n_segments"] = len(segments)
    metrics["n_pieces"] = len(pieces)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    metrics["pseudo_stretches"] = float(np.mean(pseudo))
    held_out = None
    calibration = (np.concatenate(oof_logits), np.concatenate(oof_classes), "same run")
    if by_log:
        held_true, held_pred, held_logits, held_classes, rights, scoreds = (
            list(c) for c in zip(*results[blocked.k :], strict=True)
        )
        run_right: dict[int, float] = {}  # per run over its folds (one holds it out; summed in case of more)
        run_scored: dict[int, float] = {}
        for r, n in zip(rights, scoreds, strict=True):
            for g in n:
                run_right[g] = run_right.get(g, 0.0) + r.get(g, 0.0)
                run_scored[g] = run_scored.get(g, 0.0) + n[g]
        if (unseen := unseen_runs_figure(run_right, run_scored, seed=config.seed)) is not None:
            fewest = min((n for n in logs_per_class.values() if n >= 2), default=0)  # runs of a measured terrain
            metrics["unseen_runs"] = {
                **unseen.as_dict(),
                "known_stretches": int((known_of >= 0).sum()),
                "fewest_runs": fewest,
            }
        held_out = np.concatenate(held_true), np.concatenate(held_pred)
        if sum(len(c) for c in held_classes):
            calibration = (np.concatenate(held_logits), np.concatenate(held_classes), "held-out logs")
        if len(held_out[0]):
            m = classification_metrics(*held_out, classes)
            metrics["held_out_logs"] = {
                "accuracy": m["accuracy"],
                "macro_f1": m["macro_f1"],
                "per_class_recall": m["per_class_recall"],  # the terrains measured: those in two logs
                "folds": len(by_log),
                "logs": len({s[0] for s in segments}),
                "n": m["n"],
            }
    if blocked.k > 1:
        metrics["estimate"] = terrain_estimate(classes, logs_per_class, (same_true, same_pred), held_out)
    logits, truth, source = calibration
    temperature = fit_temperature(logits, truth) if config.calibrate and len(truth) else 1.0
    for model in models:
        scale_head(model, temperature)
    metrics["calibration"] = {"temperature": temperature, "on": source if temperature != 1.0 else None, "n": len(truth)}
    drift = fit_drift(models, trained_rows, oof_rows, seed=config.seed, rows_kept=config.reference_rows)
    if blocked.k > 1 and (relation := held_out_relation(drift, models, oof_rows, right)):
        metrics["drift_accuracy"] = relation
    return ClassifierFit(
        models,
        metrics,
        histories,
        [blocked.held_out(f) for f in range(blocked.k)],
        [(p.segment, p.start, p.stop) for p in blocked.pieces],
        drift=drift,
    )
