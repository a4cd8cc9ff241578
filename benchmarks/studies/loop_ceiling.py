"""The ceiling of "the model that ships learns what the session knows": every step of the session's runs labelled
with its true terrain, stage 2 fitted, the bundle scored on the runs kept out of the session.

    python benchmarks/studies/loop_ceiling.py [--seed S] [--labelled-per-terrain 1] [--model minirocket]

The session is `loop_borealtc.py new-runs --far-per-terrain 2`'s (the same seed draws the same runs); no method that
teaches stage 2 from the session (self-training, distillation from its blend) can know more of the session's runs
than their truth, so on runs of this robot the far-run figure this prints bounds what such a method buys. Skips with
a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from loop_borealtc import DATA, build

import labeling
from sessions import Session
from workbench.cycle import active_bundle, train_classifier, train_stage1
from workbench.evaluation import read_far_runs, score_far


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--seed", type=int, default=1)
    args.add_argument("--labelled-per-terrain", type=int, default=1)
    args.add_argument("--far-per-terrain", type=int, default=2)
    args.add_argument("--model", default=None, help="stage 2's family (default: the session's)")
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC's runs are needed)")
        return 0
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder, reference, far = build(
            Path(tmp) / "s",
            "new-runs",
            per_terrain=1,
            changes=26,
            seed=opts.seed,
            far_per_terrain=opts.far_per_terrain,
            labelled_per_terrain=opts.labelled_per_terrain,
        )
        with Session.open(folder) as s:
            for log in s.logs():  # the truth over every step nobody labelled
                covered = [(g.start, g.stop) for g in s.segments(log.id)]
                for a, b, terrain in s.reference(log.id):
                    for p, q in labeling.uncovered(a, b, covered):
                        s.add_segment(log.id, p, q, terrain, author="truth")
            train_stage1(s)
            train_classifier(s, warm_start=False, model=opts.model)
            bundle = active_bundle(s)[1]
            runs = read_far_runs(far, reference, bundle, session_logs=[x.name for x in s.logs()])
            got = score_far(bundle, runs)
            n = len(s.logs())
    per = ", ".join(f"{k} {100 * v:.1f}" for k, v in sorted(got.per_log.items()))
    family = opts.model or "default family"
    print(f"every step of the session's {n} runs labelled with its truth ({family}, seed {opts.seed})")
    far_runs = f"the shipped model on {len(got.per_log)} far runs"
    print(f"{far_runs}: {100 * got.accuracy:.1f} % (balanced {100 * got.balanced:.1f})")
    print(f"per far run (%): {per}")
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
