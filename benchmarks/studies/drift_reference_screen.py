"""Screen: how many labelled frames each member's drift reference keeps (``WindowFitConfig.reference_rows``), judged
by the AUROC of drift for telling a wrong prediction and by the per-run figure expected at the drift, on BorealTC's
inner folds by run (``--inner F``: outer fold F's training runs; its test runs never read). The nearest-neighbour
search over the reference is most of a rescoring's drift time (benchmarks/results/speed.md), and it is linear in the
rows kept. At ``--labelled 0.5`` every member had more labelled frames than 2,048, so each setting binds (counted
at b4851a7, whose version of this script recorded them); at 0.1 fewer than 1,024.

    python benchmarks/studies/drift_reference_screen.py --inner 1 [--rows 2048 1024 512] [--labelled 0.5] [--seed S]

About 2 minutes per row setting on 2 cores. Skips with a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np
from study_common import RATE_HZ, borealtc_arguments, borealtc_runs

WITHIN = 0.10


def main() -> int:
    args = borealtc_arguments(__doc__)
    args.add_argument("--rows", type=int, nargs="+", default=[2048, 1024, 512], help="reference rows per member")
    args.add_argument("--labelled", type=float, default=0.5, help="share of the training partitions labelled")
    opts = args.parse_args()
    if (data := borealtc_runs(opts)) is None:
        return 0
    runs, labels, classes, fit = data
    from workbench.evaluation import borealtc_window_protocol

    print(
        "| reference rows per member | AUROC of drift for errors (folds) | mean | drifted share "
        "| expected at drift within 10 points of the run |"
    )
    print("| --- | --- | --- | --- | --- |")
    for n in opts.rows:
        t0 = time.monotonic()
        results = borealtc_window_protocol(
            runs,
            labels,
            classes,
            rate_hz=RATE_HZ,
            labelled=opts.labelled,
            split="runs",
            seed=opts.seed,
            fit=replace(fit, reference_rows=n),
            log=lambda _: None,
        )
        auroc = [r.metrics["drift_error_auroc"] for r in results]
        share = np.mean([r.metrics["drifted_share"] for r in results])
        rows = [r for res in results for r in res.metrics["runs"]]
        truth = np.asarray([r["accuracy"] for r in rows])
        exp = np.asarray([np.nan if r["expected"] is None else r["expected"] for r in rows], float)
        within = np.nanmean(np.abs(exp - truth) <= WITHIN + 1e-9)
        print(
            f"| {n} | {', '.join(f'{a:.3f}' for a in auroc)} | **{np.mean(auroc):.3f}** | {share:.1%} | "
            f"{within:.0%} of {len(rows)} runs | ({time.monotonic() - t0:.0f} s)",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
