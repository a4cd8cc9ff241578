"""``workbench evaluate ... --simulate``: label-efficiency curves of the suggestion strategies.

Wires ``labeling.simulate`` (oracle, loop, curves) to the model: stage 1 trains once without labels and its features
are cached; every round retrains stage 2 from scratch on every label so far (the model a UI Retrain ends with, after
its quick fine-tune), rescores the pool and measures held-out accuracy.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

import numpy as np

import labeling
from training import (
    FeatureMode,
    FramePredictorFit,
    Normalizer,
    Piece,
    TrainConfig,
    classification_metrics,
    fit_classifier,
    fit_predictor,
    log_frames,
    run_classifiers,
    run_predictor,
)

from ..cycle import STRETCH_S, SUGGESTION_S, consistency_pairs, score_logs, suggestion_lengths
from ..retrain import RETRAIN
from .curves_plot import plot_curves
from .evaluate_spectral import window_inputs
from .evaluate_windows import outer_folds, partitions, windows
from .sim_stage1 import frame_stage1, log_spectra, unit_spectra
from .window_learner import WindowLearner


@dataclass(frozen=True)
class SimSettings:
    """Sizes of the simulation (small models: every round retrains)."""

    strategies: tuple[str, ...] = ("random", "combined")
    model: str = "default"  # stage 2's family: "default" (window classifier, RETRAIN.window) or "paper" (LSTM)
    seeds: int = 3
    rounds: int = 8
    batch: int = 4
    hidden: int = 64
    stage1_epochs: int = 20  # paper family's LSTM (or the default family's with stage1="lstm")
    stage1_steps: int = FramePredictorFit.steps  # the default family's own next-frame predictor: its fixed budget
    # Stage 2 stops as the UI's Retrain does (workbench.retrain.RETRAIN). The 40 epochs with patience 8
    # used before stopped so early that one set of demo labels (181 s) gave 68.6, 69.0 and 79.8 % over three
    # training seeds, against 75.8, 73.4 and 73.8 % with these: the curves measured the training's luck.
    stage2_epochs: int = RETRAIN.classifier.max_epochs
    stage2_patience: int = RETRAIN.classifier.patience
    folds: int = 3  # paper family: ensemble members (disagreement needs more than one); the default's are RETRAIN's
    consistency: float = TrainConfig.consistency  # weight of stage 2's term on unlabelled neighbours (0: labels only)
    feature_mode: FeatureMode = "hidden+surprise"  # what stage 1 hands stage 2 (and the suggestions' embeddings)
    warm_start: bool = False  # start each round from the previous round's models instead of from scratch
    # Length of one suggestion, s; None: the UI's (workbench.cycle.SUGGESTION_S) on demo logs, a whole 5 s
    # partition on BorealTC (the protocol's unit; 5 / segment_s equal pieces of each when given).
    segment_s: float | None = None
    device: str = "cpu"  # where both stages train and run ("cuda": every fit and pass on the GPU)
    # Default family: the stage 1 drawing the surprise and the suggestions' embeddings: its own next-frame predictor
    # ("own", as `workbench train` trains it) or the paper's LSTM (as sessions trained before it had), to compare.
    stage1: Literal["own", "lstm"] = "own"
    # BorealTC: the outer folds stratified over partitions (the authors') or holding out whole runs (the test
    # partitions' runs never in the pool)
    split: Literal["partitions", "runs"] = "partitions"


class FeatureLearner:
    """Retrains stage 2 on cached features of the pool and reports pool scores and held-out accuracy.

    ``train_features(labels)`` gives the features and segments stage 2 trains on (the pool's own features, or
    windows cut from them to match how the test data is classified) and the unlabelled neighbour pairs of its
    consistency term; ``test_predict(models)`` the held-out predictions and truth.
    """

    def __init__(
        self,
        pool_features: list[np.ndarray],
        pool_error: list[np.ndarray],
        classes: Sequence[str],
        config: TrainConfig,
        hidden: int,
        train_features: Callable[[Sequence[labeling.Labelled]], tuple[list[np.ndarray], list, list]],
        test_predict: Callable[[list], tuple[np.ndarray, np.ndarray]],
        *,
        warm_start: bool = False,
    ) -> None:
        self.pool_features, self.pool_error = pool_features, pool_error
        self.classes, self.config, self.hidden = classes, config, hidden
        self.train_features, self.test_predict = train_features, test_predict
        self.models = None
        self.warm_start = warm_start

    def __call__(self, labels: Sequence[labeling.Labelled]) -> labeling.Round:
        if not labels:
            self.models = None
            return labeling.Round([labeling.LogScores(e) for e in self.pool_error], float("nan"))
        feats, segments, pairs = self.train_features(labels)
        fit = fit_classifier(
            feats,
            segments,
            self.classes,
            config=self.config,
            hidden=self.hidden,
            init=self.models if self.warm_start else None,
            pairs=pairs,
        )
        self.models = fit.models
        scores = score_logs(self.models, self.pool_features, self.pool_error, batch=256, device=self.config.device)
        y_true, y_pred = self.test_predict(self.models)
        m = classification_metrics(y_true, y_pred, self.classes)
        return labeling.Round(scores, m["accuracy"], m["macro_f1"])


def _run(learner_for_seed, truth, classes, settings: SimSettings, *, max_len, min_len, change_points, embeddings, log):
    curves: dict[str, list] = {s: [] for s in settings.strategies}
    for seed in range(settings.seeds):
        for strategy in settings.strategies:
            learner = learner_for_seed(seed)
            curve = labeling.simulate(
                learner,
                truth(seed),
                strategy=strategy,
                rounds=settings.rounds,
                batch=settings.batch,
                classes=classes,
                change_points=change_points(seed),
                max_len=max_len,
                min_len=min_len,
                embeddings=embeddings(seed),
                seed=seed,
                log=log,
            )
            curves[strategy].append(curve)
    return curves


def _ratio(r: float) -> str:
    return f"{r:.2f}×" if np.isfinite(r) else "never"


def report(curves, *, total: int, rate_hz: float, title: str, out: Path | None) -> str:
    """Table, the savings of each strategy against random, and the plot (when ``out`` is given)."""
    lines = [f"### {title}", "", labeling.table(curves, total_samples=total, rate_hz=rate_hz), ""]
    if "random" in curves:
        for k in curves:
            if k == "random":
                continue
            s = labeling.savings(curves, method=k)
            x, acc, t, ratio = s["rounds"][-1]
            target = f"random's final accuracy ({100 * acc:.2f} % at {x / rate_hz:.0f} s labelled)"
            if np.isfinite(t):
                lines.append(f"- `{k}` reaches {target} with {t / rate_hz:.0f} s: {ratio:.2f}× the labelled time")
            else:
                lines.append(f"- `{k}` does not reach {target} in these rounds")
            lines.append("  - against each of random's rounds: " + ", ".join(_ratio(r[3]) for r in s["rounds"]))
            if len(curves[k]) > 1:
                boot = labeling.bootstrap_final_ratio(curves, method=k)
                lo, hi = (np.quantile(boot, q, method="nearest") for q in (0.05, 0.95))
                lines.append(
                    f"  - seeds resampled (paired bootstrap, {len(boot)} draws): median {_ratio(np.median(boot))}, "
                    f"5–95 % {_ratio(lo)} to {_ratio(hi)}; at most 0.5× in {np.mean(boot <= 0.5):.0%} of draws"
                )
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        name = title.lower().split()[0]
        png = plot_curves(curves, out / f"simulate-{name}.png", total_samples=total, rate_hz=rate_hz, title=title)
        lines.append(f"\nplot: {png}")
    return "\n".join(lines)


def _default_learner(spectra, pool, test, truth, errors, cps, classes, rate_hz, seed) -> WindowLearner:
    """The default family's learner on demo-style logs."""

    def test_predict(models):
        probs = run_classifiers(models, [spectra[i] for i in test], batch=256)
        y_true = np.concatenate([truth[i] for i in test])
        y_pred = np.concatenate([p.mean(0).argmax(-1) for p in probs])
        known = y_true >= 0
        return y_true[known], y_pred[known]

    return WindowLearner(
        [spectra[i] for i in pool],
        [errors[i] for i in pool],
        classes,
        replace(RETRAIN.window, seed=seed),
        change_points=cps,
        longest=int(STRETCH_S * rate_hz),
        test_predict=test_predict,
    )


def simulate_logs(
    logs: Sequence[np.ndarray],
    truth: Sequence[np.ndarray],
    classes: Sequence[str],
    *,
    rate_hz: float = 100.0,
    settings: SimSettings = SimSettings(),
    out: Path | None = None,
    log=print,
) -> str:
    """Demo-style logs with per-sample truth: a third of the logs held out, suggestions on the rest as long as the
    UI's (half to all of ``segment_s``)."""
    if settings.model == "default" and settings.stage1 == "own":
        normalizer = Normalizer.fit(list(logs))
        spectra = log_spectra(logs, normalizer, rate_hz)
        errors, feats = frame_stage1(
            [s.frames for s in spectra], spectra, spectra[0].config, steps=settings.stage1_steps
        )
        log(f"stage 1 on {len(logs)} logs (no labels): the next-frame predictor; stage 2 on the default family")
    else:
        cfg1 = TrainConfig(max_epochs=settings.stage1_epochs, patience=5, seed=0, device=settings.device)
        pfit = fit_predictor(list(logs), config=cfg1, hidden=settings.hidden)
        normalizer = pfit.normalizer
        stage2 = "the default family" if settings.model == "default" else f"{settings.feature_mode} features"
        log(f"stage 1 on {len(logs)} logs (no labels): {len(pfit.history)} epochs of the LSTM; stage 2 on {stage2}")
        outs = run_predictor(pfit.model, normalizer, list(logs), device=settings.device)
        feats = [o.features(settings.feature_mode) for o in outs]
        errors = [np.square(o.error).mean(1) for o in outs]
        spectra = log_spectra(logs, normalizer, rate_hz) if settings.model == "default" else []
    order = np.random.default_rng(0).permutation(len(logs))
    test = np.sort(order[: max(1, len(logs) // 3)])
    pool = np.sort(order[len(test) :])
    pool_truth = [truth[i] for i in pool]
    # change points on the signals and the surprise together, as the UI computes them
    cps = [labeling.change_points(np.column_stack([normalizer(logs[i]), errors[i]]), block=25) for i in pool]
    cfg2 = TrainConfig(
        max_epochs=settings.stage2_epochs,
        patience=settings.stage2_patience,
        k_folds=settings.folds,
        consistency=settings.consistency,
        device=settings.device,
    )

    def test_predict(models):
        probs = run_classifiers(models, [feats[i] for i in test], batch=256, device=settings.device)
        y_true = np.concatenate([truth[i] for i in test])
        y_pred = np.concatenate([p.mean(0).argmax(-1) for p in probs])
        known = y_true >= 0
        return y_true[known], y_pred[known]

    pool_feats = [feats[i] for i in pool]
    # neighbours as the UI's Retrain pairs them (workbench.stage_inputs.consistency_pairs)
    pairs = []
    if settings.consistency > 0:
        pairs = consistency_pairs([len(f) for f in pool_feats], cps, cfg2)
        log(f"consistency {settings.consistency:g}: {len(pairs)} pairs of unlabelled neighbouring windows in the pool")

    def learner(seed: int) -> FeatureLearner | WindowLearner:
        if settings.model == "default":
            return _default_learner(spectra, pool, test, truth, errors, cps, classes, rate_hz, seed)
        return FeatureLearner(
            pool_feats,
            [errors[i] for i in pool],
            classes,
            replace(cfg2, seed=seed),
            settings.hidden,
            lambda labels: (pool_feats, list(labels), pairs),
            test_predict,
            warm_start=settings.warm_start,
        )

    total = sum(len(t) for t in pool_truth)
    longest, shortest = suggestion_lengths(rate_hz, seconds=settings.segment_s or SUGGESTION_S)
    # Accuracy moves in steps of whole terrain patches: with few held-out patches one patch is several points
    held = [truth[i] for i in test]
    patches = sum(int((t[np.r_[True, np.diff(t) != 0]] >= 0).sum()) for t in held if len(t))  # runs of a known class
    log(
        f"pool: {len(pool)} logs, {total / rate_hz / 60:.1f} min; held out: {len(test)} logs, "
        f"{sum(map(len, held)) / rate_hz / 60:.1f} min, {patches} terrain patches; "
        f"suggestions of {shortest / rate_hz:g}–{longest / rate_hz:g} s"
    )
    curves = _run(
        learner,
        lambda s: pool_truth,
        classes,
        settings,
        max_len=longest,
        min_len=shortest,
        change_points=lambda s: cps,
        embeddings=lambda s: [feats[i] for i in pool],
        log=log,
    )
    return report(curves, total=total, rate_hz=rate_hz, title="Demo logs (held-out logs)", out=out)


def simulate_partitions(
    runs: Sequence[np.ndarray],
    labels: Sequence[int],
    classes: Sequence[str],
    *,
    rate_hz: float = 100.0,
    settings: SimSettings = SimSettings(),
    out: Path | None = None,
    log=print,
) -> str:
    """BorealTC's protocol: the pool is a fold's training partitions (one suggestion = one 5 s partition, or one of
    its ``5 / segment_s`` equal pieces), accuracy on the test partitions' 1.7 s windows; seed ``s`` uses outer fold
    ``s + 1``.

    Each piece goes through stage 1 from a zero state, as the test windows do: a piece read from a pass over its
    whole partition would carry the partition's start-up transient in its first piece only, and the suggestions'
    embeddings would then sort pieces by their place in the partition rather than by terrain.
    """
    size, win = round(5 * rate_hz), round(1.7 * rate_hz)
    pieces = max(1, round(5 / settings.segment_s)) if settings.segment_s else 1
    parts, y, run_of = partitions(runs, labels, size)
    cuts = labeling.spans(size, np.zeros(0, np.int64), max_len=-(-size // pieces))
    units = [(i, a, b) for i in range(len(parts)) for a, b in cuts]  # the pool's "logs": pieces of partitions
    spectral_cache: dict = {}
    if settings.model == "default" and settings.stage1 == "own":
        # as a session of these runs would: the predictor trains on whole runs, each piece is read from a fresh start
        normalizer = Normalizer.fit(parts)
        front = unit_spectra(parts, units, normalizer, rate_hz, spectral_cache)
        whole = [log_frames(r, front, transform=normalizer) for r in runs]
        errors, feats = frame_stage1(whole, spectral_cache["units"], front, steps=settings.stage1_steps)
        log(f"stage 1 on all {len(runs)} runs (no labels): the next-frame predictor; stage 2 on the default family")
    else:
        cfg1 = TrainConfig(max_epochs=settings.stage1_epochs, patience=5, seed=0, piece=size, device=settings.device)
        pfit = fit_predictor(parts, config=cfg1, hidden=settings.hidden)
        normalizer = pfit.normalizer
        stage2 = "the default family" if settings.model == "default" else f"{settings.feature_mode} features"
        log(
            f"stage 1 on all {len(parts)} partitions (no labels): {len(pfit.history)} epochs of the LSTM; "
            f"stage 2 on {stage2}"
        )
        outs = run_predictor(
            pfit.model, normalizer, [parts[i][a:b] for i, a, b in units], batch=512, device=settings.device
        )
        feats = [o.features(settings.feature_mode) for o in outs]
        errors = [np.square(o.error).mean(1) for o in outs]
    folds = outer_folds(y, run_of, split=settings.split, folds=5, seed=0)  # the protocol's, either split
    in_fold = [np.isin([i for i, _, _ in units], folds[f][0]).nonzero()[0] for f in range(len(folds))]
    cfg2 = TrainConfig(
        max_epochs=settings.stage2_epochs,
        patience=settings.stage2_patience,
        k_folds=settings.folds,
        context=0,
        label_piece=win,
        consistency=settings.consistency,
        device=settings.device,
    )
    window_cache: dict[tuple[int, int, int], list[np.ndarray]] = {}

    def window_features(u: int, a: int, b: int) -> list[np.ndarray]:
        # zero-state windows of the labelled stretch, as the test windows are classified (evaluate_windows); a
        # stretch shorter than a window is one window
        if (u, a, b) not in window_cache:
            i, start, _ = units[u]
            w, _ = windows([parts[i][start + a : start + b]], min(win, b - a), round(0.5 * rate_hz))
            outs_w = run_predictor(pfit.model, normalizer, w, device=settings.device)
            window_cache[u, a, b] = [o.features(settings.feature_mode) for o in outs_w]
        return window_cache[u, a, b]

    test_cache: dict[int, tuple[list[np.ndarray], np.ndarray]] = {}

    def test_windows(fold: int) -> tuple[list[np.ndarray], np.ndarray]:
        # every strategy of a seed shares the fold: its test windows go through stage 1 once
        if fold not in test_cache:
            test_w, owner = windows([parts[i] for i in folds[fold][1]], win, round(0.5 * rate_hz))
            outs_w = run_predictor(pfit.model, normalizer, test_w, batch=512, device=settings.device)
            test_cache[fold] = [o.features(settings.feature_mode) for o in outs_w], y[folds[fold][1]][owner]
        return test_cache[fold]

    neighbour_cache: dict[int, tuple[list[np.ndarray], list[tuple[Piece, Piece]]]] = {}

    def neighbours(fold: int) -> tuple[list[np.ndarray], list[tuple[Piece, Piece]]]:
        # The consistency term's pairs: a window of a pool partition with a window of the next partition of the same
        # run (5 s on, one terrain: BorealTC's runs have no change point), through stage 1 as the test windows are.
        if fold not in neighbour_cache:
            pool_parts = folds[fold][0]
            w, owner = windows([parts[i] for i in pool_parts], win, round(0.5 * rate_hz))
            outs_w = run_predictor(pfit.model, normalizer, w, batch=512, device=settings.device)
            at = {int(p): np.flatnonzero(owner == k) for k, p in enumerate(pool_parts)}
            pairs = [
                (Piece(int(i), 0, win, 0), Piece(int(j), 0, win, 0))
                for p in pool_parts
                if p + 1 in at and run_of[p] == run_of[p + 1]
                for i in at[int(p)]
                for j in at[int(p) + 1]
            ]
            neighbour_cache[fold] = [o.features(settings.feature_mode) for o in outs_w], pairs
        return neighbour_cache[fold]

    def default_learner(seed: int) -> WindowLearner:
        # the default family: each pool piece's frames as the session computes them; test windows on their own
        fold = seed % len(folds)
        front = unit_spectra(parts, units, normalizer, rate_hz, spectral_cache)
        if fold not in spectral_cache:
            test_parts = [parts[i] for i in folds[fold][1]]
            spectral_cache[fold] = window_inputs(test_parts, win, round(0.5 * rate_hz), front, normalizer)
        x_test, owner = spectral_cache[fold]
        y_test = y[folds[fold][1]][owner]

        def test_predict(models):
            probs = run_classifiers(models, [x_test])[0].mean(0)  # windows as steps: the model is per step
            return y_test, probs.argmax(-1)

        pool = in_fold[fold]
        return WindowLearner(
            [spectral_cache["units"][u] for u in pool],
            [errors[u] for u in pool],
            classes,
            replace(RETRAIN.window, seed=seed),
            change_points=None,
            longest=size,
            test_predict=test_predict,
        )

    def learner(seed: int) -> FeatureLearner | WindowLearner:
        if settings.model == "default":
            return default_learner(seed)
        pool = in_fold[seed % len(folds)]
        test_feats, y_test = test_windows(seed % len(folds))

        def train_features(lab):
            f, segs = [], []
            for log_i, a, b, cls in lab:
                for w in window_features(int(pool[log_i]), a, b):
                    f.append(w)
                    segs.append((len(f) - 1, 0, len(w), cls))
            if settings.consistency <= 0:
                return f, segs, []
            unlabelled, pairs = neighbours(seed % len(folds))
            # the pool's windows go after the labelled ones: the pairs' indices shift by their count
            shift = len(f)
            pairs = [(replace(a, seq=a.seq + shift), replace(b, seq=b.seq + shift)) for a, b in pairs]
            return f + unlabelled, segs, pairs

        def test_predict(models):
            probs = run_classifiers(models, test_feats, batch=512, device=settings.device)
            return y_test, np.array([p.mean(0)[-1].argmax() for p in probs])

        return FeatureLearner(
            [feats[u] for u in pool],
            [errors[u] for u in pool],
            classes,
            replace(cfg2, seed=seed),
            settings.hidden,
            train_features,
            test_predict,
            warm_start=settings.warm_start,
        )

    def truth(seed: int) -> list[np.ndarray]:
        return [np.full(units[u][2] - units[u][1], y[units[u][0]]) for u in in_fold[seed % len(folds)]]

    total = sum(units[u][2] - units[u][1] for u in in_fold[0])
    longest, shortest = max(b - a for a, b in cuts), min(b - a for a, b in cuts)
    log(
        f"pool: {len(folds[0][0])} training partitions ({total / rate_hz / 60:.1f} min) per fold, "
        f"{pieces} suggestion(s) of {longest / rate_hz:.2f} s in each"
    )
    curves = _run(
        learner,
        truth,
        classes,
        settings,
        max_len=longest,
        min_len=shortest,
        change_points=lambda s: None,
        embeddings=lambda s: [feats[u] for u in in_fold[s % len(folds)]],
        log=log,
    )
    protocol = "folds holding out whole runs" if settings.split == "runs" else "partition protocol"
    title = f"BorealTC ({protocol}" + (f", {pieces} suggestions a partition)" if pieces > 1 else ")")
    return report(curves, total=total, rate_hz=rate_hz, title=title, out=out)
