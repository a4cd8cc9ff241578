"""Kept: the spectral front end (every family but the paper's reads it). A logistic regression on it alone scored
83.66 % at 10 % of labels on the authors' folds, against 74.2 % for the paper's LSTMs
(benchmarks/results/raw/protocols/notebook-default-family-screens-2026-11-28.md).

How far the spectral front end alone carries on BorealTC: a logistic regression on window summaries of
``training.spectral_cnn`` frames, under both protocols, with its one setting chosen on inner folds only.

The first measurement of the classifier issue's default family: no stage 1, no semi-supervision, the simplest
learner on the front end, so later parts can be measured against it by leaving them out.

- **partition protocol** (the authors'): 5 s partitions, stratified 5 folds over partitions, test windows of 1.7 s
  every 0.1 s classified on their own;
- **unseen runs**: the same windows, folds that hold out whole runs (neighbouring partitions of one run never sit
  on both sides).

Labelled: a stratified share of the training partitions (seeded as ``workbench evaluate borealtc`` does). The
regularisation ``C`` is chosen by grouped inner folds over the labelled partitions; the test fold scores once.

    python benchmarks/studies/spectral_baseline.py ../shared/data/borealtc --labelled 0.05 0.1 1.0
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold, StratifiedKFold
from sklearn.neural_network import MLPClassifier
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from training import SpectralConfig, classification_metrics, frame_features, split_channels
from workbench.evaluation import load_runs, partitions

RATE = 100.0
PARTITION, WINDOW, STRIDE, TRAIN_STRIDE = 500, 170, 10, 50  # samples: 5 s, 1.7 s, 0.1 s, 0.5 s
C_GRID = (0.01, 0.1, 1.0, 10.0)
AGREE = 0.9  # share of a partition's windows that must agree before it is pseudo-labelled


def window_features(part: np.ndarray, config: SpectralConfig, stride: int) -> np.ndarray:
    """Mean and spread of the frames inside each window of one partition: ``(W, 2F)``."""
    out = []
    for start in range(0, len(part) - WINDOW + 1, stride):
        f = frame_features(part[start : start + WINDOW], config)  # (frames, F)
        out.append(np.concatenate([f.mean(0), f.std(0)]))
    return np.asarray(out, np.float32)


LEARNER = "logistic"  # set from --learner


def make_model(c: float, seed: int):
    """The learner at inverse regularisation ``c``: a logistic regression, or a one-hidden-layer network with
    weight decay ``1 / c`` (128 units, Adam, 200 epochs at most)."""
    if LEARNER == "mlp":
        # 200 epochs at most is the setting, not a failure: one warning a fit would bury the table
        warnings.filterwarnings("ignore", category=ConvergenceWarning)
        net = MLPClassifier(hidden_layer_sizes=(128,), alpha=1.0 / c, max_iter=200, random_state=seed)
        return make_pipeline(StandardScaler(), net)
    return make_pipeline(StandardScaler(), LogisticRegression(C=c, max_iter=2000, random_state=seed))


def fit(xs: dict[str, np.ndarray], y: np.ndarray, groups: np.ndarray, seed: int) -> tuple[object, str, float]:
    """Logistic regression with the front-end variant and ``C`` chosen by grouped inner folds (groups: partitions)
    on the labelled training data only."""
    n_inner = min(3, len(np.unique(groups)))
    best, choice = -1.0, (next(iter(xs)), C_GRID[0])
    if n_inner >= 2:
        for variant, x in xs.items():
            for c in C_GRID:
                scores = []
                for tr, va in GroupKFold(n_inner).split(x, y, groups):
                    model = make_model(c, seed)
                    model.fit(x[tr], y[tr])
                    scores.append((model.predict(x[va]) == y[va]).mean())
                if np.mean(scores) > best:
                    best, choice = float(np.mean(scores)), (variant, c)
    variant, c = choice
    model = make_model(c, seed)
    model.fit(xs[variant], y)
    return model, variant, c


def run(folder: Path, labelled: list[float], seed: int, variants: list[str], self_training: list[bool]) -> None:
    runs, terrains, _ = load_runs(folder)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    fast, slow = split_channels(np.concatenate(runs[:5]))
    configs = {v: SpectralConfig(frame=40, hop=20, fast=fast, slow=slow, detrend=v == "detrend") for v in variants}
    config = next(iter(configs.values()))
    parts, y, run_of = partitions(runs, labels, PARTITION)
    t0 = time.perf_counter()
    test_x = {v: [window_features(p, cfg, STRIDE) for p in parts] for v, cfg in configs.items()}
    train_x = {v: [window_features(p, cfg, TRAIN_STRIDE) for p in parts] for v, cfg in configs.items()}
    print(
        f"BorealTC: {len(runs)} runs, {len(parts)} partitions; fast channels {fast}, slow {slow}; "
        f"{config.width} features a frame; features in {time.perf_counter() - t0:.0f} s",
        flush=True,
    )
    splits = {
        "partitions (authors' 5 folds)": list(StratifiedKFold(5, shuffle=True, random_state=seed).split(parts, y)),
        "unseen runs (5 folds by run)": list(
            StratifiedGroupKFold(5, shuffle=True, random_state=seed).split(parts, y, run_of)
        ),
    }
    print("| protocol | labelled | fold accuracies (%) | mean (%) | macro-F1 | front end, C chosen |")
    print("| --- | --- | --- | --- | --- | --- |")
    for (name, folds), self_train, share in itertools.product(splits.items(), self_training, labelled):
        if share >= 1.0 and self_train:
            continue  # nothing is unlabelled
        accs, f1s, cs, pseudo = [], [], [], []
        for fold, (train_idx, test_idx) in enumerate(folds, start=1):
            rng = np.random.default_rng(seed + fold)
            chosen = _stratified_share(train_idx, y, share, rng)
            first = train_x[variants[0]]
            xs = {v: np.concatenate([train_x[v][i] for i in chosen]) for v in variants}
            yy = np.concatenate([np.full(len(first[i]), y[i]) for i in chosen])
            groups = np.concatenate([np.full(len(first[i]), i) for i in chosen])
            model, variant, c = fit(xs, yy, groups, seed)
            if self_train:
                unlabelled = np.setdiff1d(train_idx, chosen)
                model, n_pseudo = pseudo_label_refit(
                    model, train_x[variant], chosen, unlabelled, y, variant_c=c, seed=seed
                )
                pseudo.append(n_pseudo)
            tx = np.concatenate([test_x[variant][i] for i in test_idx])
            ty = np.concatenate([np.full(len(test_x[variant][i]), y[i]) for i in test_idx])
            m = classification_metrics(ty, model.predict(tx), classes)
            accs.append(100 * m["accuracy"])
            f1s.append(m["macro_f1"])
            cs.append(f"{variant} {c:g}")
        cells = ", ".join(f"{a:.1f}" for a in accs)
        c_cell = ", ".join(cs)
        what = f"{share:.0%}" + (f" + self-training ({np.mean(pseudo):.0f} partitions)" if self_train else "")
        print(
            f"| {name} | {what} | {cells} | {np.mean(accs):.2f} ± {np.std(accs):.2f} | {np.mean(f1s):.3f} | {c_cell} |",
            flush=True,
        )


def pseudo_label_refit(
    model,
    windows: list[np.ndarray],
    chosen: np.ndarray,
    unlabelled: np.ndarray,
    y: np.ndarray,
    *,
    variant_c: float,
    seed: int,
    agree: float = AGREE,
) -> tuple[object, int]:
    """Self-training over stretches: an unlabelled training partition whose windows agree on one terrain (at least
    ``agree`` of them) takes it as a pseudo-label for all its windows; the model is fitted again on labels and
    pseudo-labels. The rule is fixed in advance, not tuned; test partitions are never read."""
    xs, ys = [windows[i] for i in chosen], [np.full(len(windows[i]), y[i]) for i in chosen]
    n = 0
    for u in unlabelled:
        guess = model.predict(windows[u])
        values, counts = np.unique(guess, return_counts=True)
        if counts.max() >= agree * len(guess):
            xs.append(windows[u])
            ys.append(np.full(len(guess), values[counts.argmax()]))
            n += 1
    refit = make_model(variant_c, seed)
    refit.fit(np.concatenate(xs), np.concatenate(ys))
    return refit, n


def _stratified_share(train_idx: np.ndarray, y: np.ndarray, share: float, rng: np.random.Generator) -> np.ndarray:
    if share >= 1.0:
        return np.asarray(train_idx)
    chosen = []
    for c in np.unique(y[train_idx]):
        members = train_idx[y[train_idx] == c]
        k = max(1, round(share * len(members)))
        chosen.extend(rng.choice(members, size=k, replace=False))
    return np.asarray(sorted(chosen))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--labelled", type=float, nargs="+", default=[0.05, 0.1, 1.0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--front-ends",
        nargs="+",
        default=["detrend", "level"],
        choices=["detrend", "level"],
        help="front-end variants the inner folds choose from (detrend: each frame's mean removed)",
    )
    parser.add_argument(
        "--self-training", nargs="+", default=["off", "on"], choices=["off", "on"], help="rows without and with it"
    )
    parser.add_argument("--learner", default="logistic", choices=["logistic", "mlp"])
    args = parser.parse_args()
    global LEARNER
    LEARNER = args.learner
    run(args.folder, args.labelled, args.seed, args.front_ends, [x == "on" for x in args.self_training])


if __name__ == "__main__":
    main()
