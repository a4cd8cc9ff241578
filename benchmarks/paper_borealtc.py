"""Paper-scale runs on BorealTC (about an hour on 2 CPU cores each): the published protocol, and the simulation.

    python benchmarks/paper_borealtc.py [protocol|simulate|all]

Writes Markdown reports (and the simulation plot) to ``benchmarks/results/``. Skips with a reason when
``../shared/data/borealtc`` is absent (a user's clone).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "borealtc"
RESULTS = ROOT / "benchmarks" / "results"


def main(which: str = "all") -> int:
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from workbench.evaluation import protocols as ev

    RESULTS.mkdir(parents=True, exist_ok=True)
    if which in ("protocol", "all"):
        t = time.monotonic()
        report = ev.evaluate_borealtc(DATA, labelled=0.1, variant="both", out=RESULTS / "borealtc-protocol.json")
        (RESULTS / "borealtc-protocol.md").write_text(report + f"\n\n{time.monotonic() - t:.0f} s\n")
        print(report)
    if which in ("simulate", "all"):
        t = time.monotonic()
        report = ev.simulate(
            "borealtc", DATA, strategies=("random", "combined"), seeds=3, rounds=6, batch=10, out=RESULTS
        )
        (RESULTS / "borealtc-simulate.md").write_text(report + f"\n\n{time.monotonic() - t:.0f} s\n")
        print(report)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2]))
