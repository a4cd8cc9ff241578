"""Kept as the opt-in `minirocket` family, not the default: on folds by run it scored 75.8 / 85.9 % (accuracy at 10 /
100 % of labels) against the default family's 80.6 / 90.5 %, and the two averaged 80.0 / 90.2 %
(benchmarks/results/raw/protocols/labels-2026-11-27.txt).

Issue 54, item 1: MiniRocket (``training.fit_rocket_classifier``: aeon's MiniRocket and ridge, written in
PyTorch) beside the default family on BorealTC's folds by run, alone and averaged with it (an ensemble member), at
several shares of labelled partitions. Same folds, labels and 1.7 s test windows for all three rows.

    python benchmarks/studies/minirocket_borealtc.py [--seed S] [--inner F] [--labelled 0.05 0.1 0.25 1] [--biases all]
        [--span 1.7] [--hidden H] [--no-member] [--agree A] [--unit-agree U]

``--inner F`` screens on inner folds (outer fold F's training runs only; its test runs are never read).
``--agree`` and ``--unit-agree`` screen self-training's rule (``WindowFitConfig.agree`` and ``.unit_agree``: a
training run's unlabelled partitions between change points judged together). ``--biases labelled`` draws the
transform's biases from the labelled windows only, as aeon's pipeline does; the default draws them from every
training partition, as the workbench's stage 1 reads every log. Prints, per share, each row's accuracy and balanced
accuracy (mean of the 5 folds). Skips with a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from study_common import RATE_HZ, borealtc_arguments, borealtc_runs


def balanced(metrics: dict) -> float:
    """The mean recall over the terrains in the test fold."""
    return float(np.mean(list(metrics["per_class_recall"].values())))


def main() -> int:
    args = borealtc_arguments(__doc__)
    args.add_argument("--labelled", type=float, nargs="+", default=[0.05, 0.1, 0.25, 1.0])
    args.add_argument("--biases", default="all", choices=("all", "labelled"))
    args.add_argument("--stride", type=float, default=0.5, help="seconds between MiniRocket's training windows")
    args.add_argument("--span", type=float, default=1.7, help="seconds a test window (and a step's input) spans")
    args.add_argument("--frame", type=float, default=0.4, help="seconds of the default family's short-time frames")
    args.add_argument("--hidden", type=int, default=None, help="the default family's width (WindowFitConfig.hidden)")
    args.add_argument("--unit-agree", type=float, default=None, help="WindowFitConfig.unit_agree (a screen)")
    args.add_argument("--agree", type=float, default=None, help="WindowFitConfig.agree (a screen)")
    args.add_argument("--no-member", action="store_true", help="the default family alone (a screen of its settings)")
    args.add_argument(
        "--pool-share",
        type=float,
        default=None,
        help="WindowFitConfig.pool_share: self-training's pool holds this share of its stretches' bytes, a draw of "
        "whole stretches as pool_mib draws them on fleet hours (issue 66: 0.073 is 512 MiB of 100 h, 22 channels)",
    )
    opts = args.parse_args()
    if (data := borealtc_runs(opts)) is None:
        return 0
    from workbench.evaluation import RocketMember, WindowProtocol, borealtc_window_protocol

    runs, labels, classes, fit = data
    if opts.hidden:
        fit = replace(fit, hidden=opts.hidden)
    if opts.agree is not None:
        fit = replace(fit, agree=opts.agree)
    if opts.unit_agree is not None:
        fit = replace(fit, unit_agree=opts.unit_agree)
    if opts.pool_share is not None:
        fit = replace(fit, pool_share=opts.pool_share)
    member = None if opts.no_member else RocketMember(stride=round(opts.stride * RATE_HZ), biases_from=opts.biases)
    # the default family's frames: 0.4 s (--frame) every 0.2 s, as many as the span holds (7 for 1.7 s, 16 for 3.4 s)
    protocol = WindowProtocol(
        window_s=opts.span, frames=int((opts.span - opts.frame) / 0.2 + 1e-9) + 1, frame_s=opts.frame
    )
    print(
        f"span {opts.span} s ({protocol.frames} frames of {opts.frame} s), width {fit.hidden}, "
        f"MiniRocket biases from {opts.biases}"
        + (f", stretches agreeing at {fit.agree}" if opts.agree is not None else "")
        + (f", units agreeing at {fit.unit_agree}" if fit.unit_agree else "")
    )
    columns = ["default: accuracy / balanced"] + ([] if member is None else ["MiniRocket", "mean of both"])
    print(f"| labelled | {' | '.join(columns)} | s |\n|{' --- |' * (len(columns) + 2)}")
    for share in opts.labelled:
        t0 = time.monotonic()
        res = borealtc_window_protocol(
            runs, labels, classes, rate_hz=RATE_HZ, labelled=share, split="runs", seed=opts.seed, fit=fit,
            protocol=protocol, member=member, log=lambda line: print("   ", line, flush=True),
        )  # fmt: skip
        cells = []
        rows = (lambda m: m,) if member is None else (lambda m: m, lambda m: m["member"], lambda m: m["ensemble"])
        for row in rows:
            acc = np.mean([row(r.metrics)["accuracy"] for r in res]) * 100
            bal = np.mean([balanced(row(r.metrics)) for r in res]) * 100
            cells.append(f"{acc:.1f} / {bal:.1f} %")
        print(f"| {share:.0%} | {' | '.join(cells)} | {time.monotonic() - t0:.0f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
