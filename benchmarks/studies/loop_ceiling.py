"""The ceiling of "the model that ships learns what the session knows": every step of the session's runs labelled
with its true terrain, stage 2 fitted, the bundle scored on the runs kept out of the session.

    python benchmarks/studies/loop_ceiling.py [--seed S] [--labelled-per-terrain 1] [--model minirocket]
    python benchmarks/studies/loop_ceiling.py --walks [--seed S]

The session is `loop_borealtc.py new-runs --far-per-terrain 2`'s (the same seed draws the same runs; ``--walks``:
`loop_walks.py --far 4`'s 8 walks in the session and 4 far, stand-in C); no method that
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
from sessions import IngestOptions, Session
from workbench.cycle import active_bundle, train_classifier, train_stage1
from workbench.evaluation import FarScore, read_far_runs, score_far


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    args.add_argument("--seed", type=int, default=1)
    args.add_argument("--labelled-per-terrain", type=int, default=1)
    args.add_argument("--far-per-terrain", type=int, default=2)
    args.add_argument("--model", default=None, help="stage 2's family (default: the session's)")
    args.add_argument("--walks", action="store_true", help="the demo walks of `loop_walks.py --far 4` (stand-in C)")
    opts = args.parse_args()
    if opts.walks:
        return walks_ceiling(opts.seed, model=opts.model)
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
            got, n = labelled_by_truth(s, far, reference, model=opts.model)
    report(got, n, opts.model, opts.seed, t0)
    return 0


def labelled_by_truth(
    s: Session, far: list[Path], reference: Path, *, model: str | None, options: IngestOptions | None = None
) -> tuple[FarScore, int]:
    """Every step of ``s``'s runs nobody labelled given its reference terrain, both stages fitted, the bundle scored
    on ``far`` (read with ``options``); the far runs' figures and the session's run count."""
    for log in s.logs():  # the truth over every step nobody labelled
        covered = [(g.start, g.stop) for g in s.segments(log.id)]
        for a, b, terrain in s.reference(log.id):
            for p, q in labeling.uncovered(a, b, covered):
                s.add_segment(log.id, p, q, terrain, author="truth")
    train_stage1(s)
    train_classifier(s, warm_start=False, model=model)
    bundle = active_bundle(s)[1]
    runs = read_far_runs(far, reference, bundle, session_logs=[x.name for x in s.logs()], options=options)
    return score_far(bundle, runs), len(s.logs())


def walks_ceiling(seed: int, *, model: str | None) -> int:
    """Stand-in C's ceiling: `loop_walks.py --far 4`'s walks (the same seed draws the same walks)."""
    from loop_walks import far_reference

    from workbench.demo import generate_demo_logs

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        made = generate_demo_logs(Path(tmp) / "logs", n_logs=12, minutes=4.0, seed=100 + seed)
        files, far = made[:8], made[8:]
        reference = far_reference(far, Path(tmp) / "far-reference.csv")
        with Session.create(Path(tmp) / "s") as s:
            logs = s.ingest(files)
            for name in sorted({t for x in logs for _, _, t in s.reference(x.id)}):
                s.add_terrain(name)
            got, n = labelled_by_truth(s, far, reference, model=model)
    report(got, n, model, seed, t0)
    return 0


def report(got: FarScore, n: int, model: str | None, seed: int, t0: float) -> None:
    """Print the far runs' figures."""
    per = ", ".join(f"{k} {100 * v:.1f}" for k, v in sorted(got.per_log.items()))
    family = model or "default family"
    print(f"every step of the session's {n} runs labelled with its truth ({family}, seed {seed})")
    far_runs = f"the shipped model on {len(got.per_log)} far runs"
    print(f"{far_runs}: {100 * got.accuracy:.1f} % (balanced {100 * got.balanced:.1f})")
    print(f"per far run (%): {per}")
    print(f"{time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    sys.exit(main())
