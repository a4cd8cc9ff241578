"""Issue 54's minority row on BorealTC: folds by run (5 outer folds), 10 % of the training partitions labelled, the
default family as it is; each terrain in turn kept at a tenth of its training partitions (labelled and unlabelled
alike, drawn per fold), the test folds unchanged. Prints each terrain's recall there against its recall with all its
time (the target: within 10 points).

    python benchmarks/minority_borealtc.py [--seed S] [TERRAIN ...]

About 90 s per terrain on 2 cores. Skips with a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "borealtc"
RATE_HZ = 100.0
LABELLED = 0.1
KEPT = 0.1  # the minority terrain's share of its training partitions


def recalls(parts, y, run_of, classes, *, minority: int | None, seed: int) -> tuple[dict[str, float], float]:
    """Each terrain's recall over every test window of the 5 outer folds by run, and the accuracy."""
    from dataclasses import replace

    from training import (
        Normalizer,
        SpectralConfig,
        SpectralSteps,
        WindowFitConfig,
        fit_window_classifier,
        log_frames,
        run_classifiers,
    )
    from workbench.evaluation import WindowProtocol, labelled_subset, outer_folds, window_inputs

    protocol = WindowProtocol()
    size, win, stride = (round(s * RATE_HZ) for s in (protocol.partition_s, protocol.window_s, protocol.stride_s))
    fit = replace(WindowFitConfig(), seed=seed)
    true_all, pred_all = [], []
    for fold, (train_idx, test_idx) in enumerate(
        outer_folds(y, run_of, split="runs", folds=protocol.folds, seed=seed), start=1
    ):
        if minority is not None:
            mine = train_idx[y[train_idx] == minority]
            keep = set(np.random.default_rng(fold).choice(mine, max(1, round(KEPT * len(mine))), replace=False))
            train_idx = np.asarray([i for i in train_idx if y[i] != minority or i in keep])
        train = [parts[i] for i in train_idx]
        normalizer = Normalizer.fit(train)
        config = SpectralConfig.for_log(np.concatenate(train[:50]), RATE_HZ)
        features = [SpectralSteps(log_frames(p, config, transform=normalizer), len(p), config) for p in train]
        chosen = set(labelled_subset(train_idx, y, LABELLED, seed=seed + fold).tolist())
        first = config.span - 1  # the first step whose window holds full frames only
        segments = [(j, first, size, int(y[i])) for j, i in enumerate(train_idx) if i in chosen]
        stretches = [(j, first, size) for j, i in enumerate(train_idx) if i not in chosen]
        groups = [int(run_of[i]) for i in train_idx]
        cfit = fit_window_classifier(features, segments, classes, config=fit, stretches=stretches, groups=groups)
        x, owner = window_inputs([parts[i] for i in test_idx], win, stride, config, normalizer)
        true_all.append(y[test_idx][owner])
        pred_all.append(run_classifiers(cfit.models, [x])[0].mean(0).argmax(1))
    t, p = np.concatenate(true_all), np.concatenate(pred_all)
    return {c: float((p[t == k] == k).mean()) for k, c in enumerate(classes)}, float((t == p).mean())


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("terrains", nargs="*", help="terrains to keep at a tenth (default: each in turn)")
    args.add_argument("--seed", type=int, default=0)
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from workbench.evaluation import WindowProtocol, load_runs, partitions

    runs, terrains, _ = load_runs(DATA)
    classes = sorted(set(terrains))
    size = round(WindowProtocol().partition_s * RATE_HZ)
    parts, y, run_of = partitions(runs, [classes.index(t) for t in terrains], size)
    t0 = time.monotonic()
    full, acc = recalls(parts, y, run_of, classes, minority=None, seed=opts.seed)
    print(f"all time: accuracy {acc:.1%}; recall " + ", ".join(f"{c} {r:.1%}" for c, r in full.items()), flush=True)
    for name in opts.terrains or classes:
        k = classes.index(name)
        rec, acc = recalls(parts, y, run_of, classes, minority=k, seed=opts.seed)
        drop = 100 * (full[name] - rec[name])
        print(
            f"{name} at a tenth of its time: its recall {rec[name]:.1%} against {full[name]:.1%} with all of it "
            f"({drop:.0f} points {'lower' if drop >= 0 else 'higher'}; target within 10), accuracy {acc:.1%}",
            flush=True,
        )
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
