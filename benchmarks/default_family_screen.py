"""Variants of the default family's stage 2 on BorealTC, scored on inner folds of each outer fold's training
partitions only (the outer test folds are never read): 10 % of the inner training partitions labelled, inner
validation windows of 1.7 s every 0.5 s.

    python benchmarks/default_family_screen.py --split partitions --variants base st3 spread pca64 pca32

Variants: ``base`` (the shipped rule: one round of self-training over partitions whose windows agree at 90 %),
``st3`` (three rounds), ``spread`` (pseudo-labels from label spreading over partition means, k-NN graph, instead
of self-training), ``pcaK`` (PCA whitening to K components fitted on all training partitions, then ``base``).
"""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
from sklearn.decomposition import PCA
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression
from sklearn.model_selection import GroupKFold, StratifiedGroupKFold
from sklearn.semi_supervised import LabelSpreading

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from training import Normalizer, SpectralConfig, frame_features, log_summaries, summary_windows
from workbench.evaluation import labelled_subset, load_runs, outer_folds, partitions

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "borealtc"
C_GRID = (0.01, 0.1, 1.0, 10.0)
AGREE = 0.9


def window_summaries(parts, window: int, stride: int, config: SpectralConfig, normalizer: Normalizer):
    """Every ``window``-sample window at ``stride`` of each partition, summarised on its own (mean and spread of its
    frames): ``(N, 2F)`` and the partition of each."""
    out, owner = [], []
    for i, p in enumerate(parts):
        z = normalizer(p)
        for start in range(0, len(p) - window + 1, stride):
            out.append(
                summary_windows(frame_features(z[start : start + window], config), frames_per_window=config.window)[-1]
            )
            owner.append(i)
    return np.asarray(out, np.float32), np.asarray(owner)


def _lr(x: np.ndarray, y: np.ndarray, c: float) -> LogisticRegression:
    return LogisticRegression(C=c, max_iter=1000).fit(x, y)


def _choose_c(x: np.ndarray, y: np.ndarray, groups: np.ndarray) -> float:
    scores = {
        c: sum((_lr(x[tr], y[tr], c).predict(x[va]) == y[va]).sum() for tr, va in GroupKFold(3).split(x, y, groups))
        for c in C_GRID
    }
    return max(scores, key=scores.get)


def fit_variant(
    variant: str, rows: dict[int, np.ndarray], labelled: np.ndarray, unlabelled: np.ndarray, y: np.ndarray
) -> Callable[[np.ndarray], np.ndarray]:
    """A predictor of window summaries ``(N, 2F)`` -> classes, fitted as ``variant`` says."""
    if variant.startswith("pca"):
        every = np.concatenate([rows[i] for i in [*labelled, *unlabelled]])
        project = PCA(int(variant[3:]), whiten=True, random_state=0).fit(every).transform
    else:

        def project(a: np.ndarray) -> np.ndarray:
            return a

    x = project(np.concatenate([rows[i] for i in labelled]))
    yy = np.concatenate([np.full(len(rows[i]), y[i]) for i in labelled])
    groups = np.concatenate([np.full(len(rows[i]), k) for k, i in enumerate(labelled)])
    c = _choose_c(x, yy, groups)
    model = _lr(x, yy, c)
    if variant == "spread":
        means = np.stack([project(rows[i]).mean(0) for i in [*labelled, *unlabelled]])
        target = np.concatenate([y[labelled], np.full(len(unlabelled), -1)])
        spread = LabelSpreading(kernel="knn", n_neighbors=10, alpha=0.2, max_iter=100).fit(means, target)
        dist = spread.label_distributions_[len(labelled) :]
        picked = [(i, d.argmax()) for i, d in zip(unlabelled, dist, strict=True) if d.max() >= AGREE]
    for _ in range(3 if variant == "st3" else 1):
        if variant != "spread":
            picked = []
            for i in unlabelled:
                votes = np.bincount(model.predict(project(rows[i])), minlength=len(np.unique(y)))
                if votes.max() >= AGREE * len(rows[i]):
                    picked.append((i, votes.argmax()))
        xs = [x, *(project(rows[i]) for i, _ in picked)]
        ys = [yy, *(np.full(len(rows[i]), k) for i, k in picked)]
        model = _lr(np.concatenate(xs), np.concatenate(ys), c)
    return lambda a: model.predict(project(a))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", default="partitions", choices=["partitions", "runs"])
    parser.add_argument("--variants", nargs="+", default=["base", "st3", "spread", "pca64", "pca32"])
    args = parser.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return
    warnings.simplefilter("ignore", ConvergenceWarning)
    runs, terrains, _ = load_runs(DATA)
    classes = sorted(set(terrains))
    parts, y, run_of = partitions(runs, [classes.index(t) for t in terrains], 500)
    results: dict[str, list[float]] = {v: [] for v in args.variants}
    for fold, (train, _) in enumerate(outer_folds(y, run_of, split=args.split, folds=5, seed=0), start=1):
        normalizer = Normalizer.fit([parts[i] for i in train])
        config = SpectralConfig.for_log(np.concatenate([parts[i] for i in train[:50]]), 100.0)
        skip = (config.span - config.frame) // config.hop  # frames before the first full window
        rows = {i: log_summaries(parts[i], config, transform=normalizer)[skip:] for i in train}
        every = np.concatenate(list(rows.values()))
        mean, std = every.mean(0), every.std(0) + 1e-6
        rows = {i: (r - mean) / std for i, r in rows.items()}
        groups = run_of[train] if args.split == "runs" else train
        for inner_train, inner_val in StratifiedGroupKFold(3, shuffle=True, random_state=fold).split(
            train, y[train], groups
        ):
            pool, val = train[inner_train], train[inner_val]
            labelled = labelled_subset(pool, y, 0.1, seed=fold)
            unlabelled = np.setdiff1d(pool, labelled)
            x_val, owner = window_summaries([parts[i] for i in val], 170, 50, config, normalizer)
            x_val, y_val = (x_val - mean) / std, y[val][owner]
            for variant in args.variants:
                predict = fit_variant(variant, rows, labelled, unlabelled, y)
                results[variant].append(float((predict(x_val) == y_val).mean()))
        print(f"outer fold {fold}: " + ", ".join(f"{v} {100 * np.mean(r[-3:]):.2f}" for v, r in results.items()))
    print("mean over inner folds (%): " + ", ".join(f"{v} {100 * np.mean(r):.2f}" for v, r in results.items()))


if __name__ == "__main__":
    main()
