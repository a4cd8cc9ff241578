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


def recalls(runs, labels, classes, *, minority: int | None, seed: int) -> tuple[dict[str, float], float]:
    """Each terrain's recall over every test window of the 5 outer folds by run, and the accuracy."""
    from workbench.evaluation import borealtc_window_protocol

    def keep_a_tenth(fold: int, train_idx: np.ndarray, y: np.ndarray) -> np.ndarray:
        mine = train_idx[y[train_idx] == minority]
        keep = set(np.random.default_rng(fold).choice(mine, max(1, round(KEPT * len(mine))), replace=False))
        return np.asarray([i for i in train_idx if y[i] != minority or i in keep])

    results = borealtc_window_protocol(
        runs,
        labels,
        classes,
        rate_hz=RATE_HZ,
        labelled=LABELLED,
        split="runs",
        seed=seed,
        log=lambda _: None,
        train_filter=None if minority is None else keep_a_tenth,
    )
    confusion = sum(np.asarray(r.metrics["confusion"]) for r in results)  # (K, K) rows: truth, every test window
    recall = confusion.diagonal() / np.maximum(confusion.sum(axis=1), 1)
    return dict(zip(classes, recall.tolist(), strict=True)), float(confusion.trace() / confusion.sum())


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("terrains", nargs="*", help="terrains to keep at a tenth (default: each in turn)")
    args.add_argument("--seed", type=int, default=0)
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from workbench.evaluation import load_runs

    runs, terrains, _ = load_runs(DATA)
    classes = sorted(set(terrains))
    labels = [classes.index(t) for t in terrains]
    t0 = time.monotonic()
    full, acc = recalls(runs, labels, classes, minority=None, seed=opts.seed)
    print(f"all time: accuracy {acc:.1%}; recall " + ", ".join(f"{c} {r:.1%}" for c, r in full.items()), flush=True)
    for name in opts.terrains or classes:
        k = classes.index(name)
        rec, acc = recalls(runs, labels, classes, minority=k, seed=opts.seed)
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
