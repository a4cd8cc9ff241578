"""Kept: MiniRocket's heads read at most 4,096 labelled hop rows (issue 66; benchmarks/results/fleet.md,
"MiniRocket at a fleet's hours").

The accuracy cost of that budget on BorealTC's runs, where it bites: a session of every run, a share of its time
labelled in 5 s pieces (``workbench.demo.seed_labels``; at 25 %, 5,835 labelled hop rows), `workbench train --model
minirocket` (the card's held-out-logs figure and the seconds it took), then `workbench evaluate session` (stage 2
retrained per fold without the held-out runs' labels, each held-out run scored whole against its folder name).
Run it on the code before the budget for the reference (the same script, copied there).

    python benchmarks/studies/rocket_rows_borealtc.py [--labelled 0.25] [--seed 0]

About 10 minutes on 2 cores with the budget. Skips with a reason when ``../shared/data/borealtc`` is absent.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT.parent / "shared" / "data" / "borealtc"


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--labelled", type=float, default=0.25)
    args.add_argument("--seed", type=int, default=0)
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from card_vs_session_borealtc import labelled_session

    from sessions import Session
    from workbench.cli import main as workbench
    from workbench.evaluation import evaluate_session

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder = labelled_session(Path(tmp) / "s", "pieces", opts.seed, share=opts.labelled)
        if workbench(["train", str(folder), "--stage", "predictor"]) != 0:
            raise SystemExit("workbench train --stage predictor failed")
        t1 = time.monotonic()
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            if workbench(["train", str(folder), "--stage", "classifier", "--model", "minirocket"]) != 0:
                raise SystemExit("workbench train --model minirocket failed")
        card = next((x for x in out.getvalue().splitlines() if "minirocket family" in x), "no card line")
        print(f"stage 2 (minirocket): {time.monotonic() - t1:.0f} s; {card}", flush=True)
        t2 = time.monotonic()
        with Session.open(folder) as s:
            report = evaluate_session(s, seed=opts.seed, log=lambda _: None)
        held = re.search(r"\*\*Accuracy ([\d.]+) %.*", report)
        print(held[0] if held else report)
        print(f"evaluate session: {time.monotonic() - t2:.0f} s")
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
