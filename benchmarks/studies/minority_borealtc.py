"""Kept: the logit adjustment (`WindowFitConfig.balance = "logits"`). With a terrain at a tenth of its time, its recall
rose 3 to 16 points on every terrain (mean +9.6) on the test folds
(benchmarks/results/raw/protocols/notebook-model-and-card-2026-11-27.md, "Minority terrains").

Issue 54's minority row on BorealTC: folds by run (5 outer folds), 10 % of the training partitions labelled, the
default family as it is; each terrain in turn kept at a tenth of its training partitions (labelled and unlabelled
alike, drawn per fold), the test folds unchanged. Prints each terrain's recall there against its recall with all its
time (the target: within 10 points).

    python benchmarks/studies/minority_borealtc.py [--seed S] [--balance B] [--inner F] [--minirocket] [--labelled L]
        [TERRAIN ...]

``--balance`` picks :attr:`training.WindowFitConfig.balance`. ``--inner F`` screens on inner folds: the protocol runs
on outer fold F's training runs only (5 inner folds by run over them; F's test runs are never read), as settings are
chosen. ``--minirocket`` also scores MiniRocket + ridge (``workbench.evaluation.RocketMember``) on the same folds,
labels and test windows, alone and averaged with the default family (the issue saw MiniRocket find more of a
minority class). About 90 s per terrain on 2 cores (about 3 minutes with MiniRocket). Skips with a reason when
``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import time
from functools import partial

import numpy as np
from study_common import RATE_HZ, borealtc_arguments, borealtc_runs

LABELLED = 0.1
KEPT = 0.1  # the minority terrain's share of its training partitions


ROWS = {"default": lambda m: m, "MiniRocket": lambda m: m["member"], "mean of both": lambda m: m["ensemble"]}


def recalls(
    runs, labels, classes, *, minority: int | None, seed: int, fit, minirocket: bool, labelled: float, pieces: list
) -> dict[str, tuple[dict[str, float], float]]:
    """Per row (the default family; with ``minirocket`` also MiniRocket and the mean of both): each terrain's recall
    over every test window of the 5 outer folds by run, and the accuracy. ``pieces`` gets, per fold, the minority's
    labelled 5 s pieces (the protocol's own draw)."""
    from workbench.evaluation import RocketMember, borealtc_window_protocol, labelled_subset

    def keep_a_tenth(fold: int, train_idx: np.ndarray, y: np.ndarray) -> np.ndarray:
        mine = train_idx[y[train_idx] == minority]
        keep = set(np.random.default_rng(fold).choice(mine, max(1, round(KEPT * len(mine))), replace=False))
        kept = np.asarray([i for i in train_idx if y[i] != minority or i in keep])
        pieces.append(int(np.sum(y[labelled_subset(kept, y, labelled, seed=seed + fold)] == minority)))
        return kept

    results = borealtc_window_protocol(
        runs,
        labels,
        classes,
        rate_hz=RATE_HZ,
        labelled=labelled,
        split="runs",
        seed=seed,
        fit=fit,
        log=lambda _: None,
        train_filter=None if minority is None else keep_a_tenth,
        # a new member per call: it keeps each fold's transform, whose biases come from that call's training runs
        member=RocketMember() if minirocket else None,
    )
    out = {}
    for name, row in ROWS.items() if minirocket else [("default", ROWS["default"])]:
        confusion = sum(np.asarray(row(r.metrics)["confusion"]) for r in results)  # (K, K) rows: truth
        recall = confusion.diagonal() / np.maximum(confusion.sum(axis=1), 1)
        out[name] = dict(zip(classes, recall.tolist(), strict=True)), float(confusion.trace() / confusion.sum())
    return out


def main() -> int:
    args = borealtc_arguments(__doc__)
    args.add_argument("terrains", nargs="*", help="terrains to keep at a tenth (default: each in turn)")
    args.add_argument("--minirocket", action="store_true", help="also MiniRocket + ridge, alone and averaged")
    args.add_argument("--labelled", type=float, default=LABELLED, help="share of the training partitions labelled")
    opts = args.parse_args()
    if (data := borealtc_runs(opts)) is None:
        return 0
    runs, labels, classes, fit = data
    t0 = time.monotonic()
    run = partial(
        recalls, runs, labels, classes, seed=opts.seed, fit=fit, minirocket=opts.minirocket, labelled=opts.labelled
    )
    full = run(minority=None, pieces=[])
    print(f"{opts.labelled:.0%} of the training partitions labelled", flush=True)
    for row, (rec, acc) in full.items():
        balanced = float(np.mean(list(rec.values())))
        print(
            f"{row} (balance {fit.balance}), all time: accuracy {acc:.1%}, balanced {balanced:.1%}; recall "
            + ", ".join(f"{c} {r:.1%}" for c, r in rec.items()),
            flush=True,
        )
    for name in opts.terrains or classes:
        k = classes.index(name)
        pieces: list[int] = []
        for row, (rec, acc) in run(minority=k, pieces=pieces).items():
            drop = 100 * (full[row][0][name] - rec[name])
            print(
                f"{row}: {name} at a tenth of its time: its recall {rec[name]:.1%} against {full[row][0][name]:.1%} "
                f"with all of it ({drop:.0f} points {'lower' if drop >= 0 else 'higher'}; target within 10), "
                f"accuracy {acc:.1%}; its labelled 5 s pieces per fold: {pieces}",
                flush=True,
            )
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
