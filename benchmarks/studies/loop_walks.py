"""Kept: the yardstick of issue 65 on walks whose terrain changes. `combined` 95.5 % against random's 92.7 % (seed 1)
and 93.9 against 86.3 % (seed 2) (benchmarks/results/raw/loop/notebook-new-runs-2026-11-28.md).

Issue 65's loop on demo walks whose terrain changes every 5-36 s: `workbench evaluate loop` on a session where
half the walks were labelled (10 % of their time, in 5 s pieces) and the other half have no label.

    python benchmarks/studies/loop_walks.py [--walks 8] [--minutes 4] [--seed S] [--rounds 4] [--per-round 12]
        [--person piece] [--strategies combined random ...]

The walks are the demo's (`workbench.demo`), each a run of its own (speed, gait, sensor gains, IMU mounting), their
reference from the generator's truth. ``--far N``: N more walks are kept out of the session entirely and scored after
every round by the bundle the session would export (issue 82's far runs).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from study_common import label_runs, loop_arguments, loop_settings

ROOT = Path(__file__).resolve().parents[2]


def far_reference(files: list[Path], out: Path) -> Path:
    """The far walks' truth as a label file, in seconds from each walk's start (the generator's truth files)."""
    import json

    import pandas as pd

    rows = []
    for f in files:
        truth = json.loads(f.with_name(f.stem + ".truth.json").read_text())["segments"]
        t0 = truth[0]["start"]
        rows += [(f.stem, x["start"] - t0, x["stop"] - t0, x["terrain"]) for x in truth]
    pd.DataFrame(rows, columns=["log", "start_s", "end_s", "terrain"]).to_csv(out, index=False)
    return out


def main() -> int:
    args = loop_arguments(__doc__)
    args.add_argument("--walks", type=int, default=8)
    args.add_argument("--minutes", type=float, default=4.0)
    args.add_argument("--far", type=int, default=0, help="more walks kept out of the session, scored by the bundle")
    opts = args.parse_args()
    sys.path.insert(0, str(ROOT))
    from sessions import Session
    from workbench.demo import generate_demo_logs
    from workbench.evaluation import evaluate_loop

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        made = generate_demo_logs(
            Path(tmp) / "logs", n_logs=opts.walks + opts.far, minutes=opts.minutes, seed=100 + opts.seed
        )
        files, far = made[: opts.walks], made[opts.walks :]
        reference = far_reference(far, Path(tmp) / "far-reference.csv") if far else None
        with Session.create(Path(tmp) / "s") as s:
            logs = s.ingest(files)
            for name in sorted({t for x in logs for _, _, t in s.reference(x.id)}):
                s.add_terrain(name)
            label_runs(s, logs[: opts.walks // 2], seed=opts.seed)
            print(f"{len(logs)} walks, {opts.walks // 2} labelled at 10 % in 5 s pieces", flush=True)
            if far:
                print(f"far: {len(far)} walks never in the session", flush=True)
            print(
                evaluate_loop(
                    s, settings=loop_settings(opts), workdir=Path(tmp), reference=reference, far=far, out=opts.out
                )
            )
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
