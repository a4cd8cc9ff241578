"""Issue 54's minority row on BorealTC: folds by run (5 outer folds), 10 % of the training partitions labelled, the
default family as it is; each terrain in turn kept at a tenth of its training partitions (labelled and unlabelled
alike, drawn per fold), the test folds unchanged. Prints each terrain's recall there against its recall with all its
time (the target: within 10 points).

    python benchmarks/minority_borealtc.py [--seed S] [--balance B] [--inner F] [TERRAIN ...]

``--balance`` picks :attr:`training.WindowFitConfig.balance`. ``--inner F`` screens on inner folds: the protocol runs
on outer fold F's training runs only (5 inner folds by run over them; F's test runs are never read), as settings are
chosen. About 90 s per terrain on 2 cores. Skips with a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np
from borealtc_runs import RATE_HZ, borealtc_arguments, borealtc_runs

LABELLED = 0.1
KEPT = 0.1  # the minority terrain's share of its training partitions


def recalls(runs, labels, classes, *, minority: int | None, seed: int, fit) -> tuple[dict[str, float], float]:
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
        fit=fit,
        log=lambda _: None,
        train_filter=None if minority is None else keep_a_tenth,
    )
    confusion = sum(np.asarray(r.metrics["confusion"]) for r in results)  # (K, K) rows: truth, every test window
    recall = confusion.diagonal() / np.maximum(confusion.sum(axis=1), 1)
    return dict(zip(classes, recall.tolist(), strict=True)), float(confusion.trace() / confusion.sum())


def main() -> int:
    args = borealtc_arguments(__doc__)
    args.add_argument("terrains", nargs="*", help="terrains to keep at a tenth (default: each in turn)")
    opts = args.parse_args()
    if (data := borealtc_runs(opts)) is None:
        return 0
    runs, labels, classes, fit = data
    t0 = time.monotonic()
    run = partial(recalls, runs, labels, classes, seed=opts.seed, fit=fit)
    full, acc = run(minority=None)
    balanced = float(np.mean(list(full.values())))
    print(
        f"balance {fit.balance}, all time: accuracy {acc:.1%}, balanced {balanced:.1%}; recall "
        + ", ".join(f"{c} {r:.1%}" for c, r in full.items()),
        flush=True,
    )
    for name in opts.terrains or classes:
        k = classes.index(name)
        rec, acc = run(minority=k)
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
