"""Kept: the card's estimate checked against `workbench evaluate session` on BorealTC sessions: 80.48 % (pieces) and
79.19 % (one run per terrain) held out (benchmarks/results/raw/protocols/notebook-model-and-card-2026-11-27.md,
"The card against `workbench evaluate session`").

Issue 54's card-against-evaluate row on BorealTC: a session of its runs, labelled as a person would, trained with
`workbench train`; the card's figure (the estimate `train` prints, and what the exported card expects of the logs
with no label at their drift) beside `workbench evaluate session` (stage 2 on the other logs' labels, each held-out
run scored whole against its folder name). The target: within 5 points.

    python benchmarks/studies/card_vs_session_borealtc.py [pieces|runs] [--seed S]

``pieces``: 10 % of the time labelled in 5 s pieces drawn inside the runs (``workbench.demo.seed_labels``).
``runs``: one whole run per terrain labelled (its longest). About 10 minutes each on 2 cores. Skips with a reason
when ``../shared/data/borealtc`` is absent.
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


def labelled_session(folder: Path, how: str, seed: int, *, share: float = 0.10) -> Path:
    """A session of BorealTC's runs (their folder names as the reference), labelled ``how`` (``pieces``: ``share``
    of the time in 5 s pieces; ``runs``: each terrain's longest run whole)."""
    from sessions import Session
    from workbench.demo import seed_labels

    with Session.create(folder) as s:
        logs = s.ingest([DATA])
        for name in sorted({t for x in logs for _, _, t in s.reference(x.id)}):
            s.add_terrain(name)
        if how == "pieces":
            seed_labels(s, share, seed=seed, segment_s=5.0, author="benchmark")
        else:
            longest: dict[str, tuple[int, int, int, int]] = {}
            for x in logs:
                for a, b, t in s.reference(x.id):
                    if b - a > longest.get(t, (0, 0, 0, 0))[3]:
                        longest[t] = (x.id, a, b, b - a)
            for t, (log_id, a, b, _) in longest.items():
                s.add_segment(log_id, a, b, t, author="benchmark")
        print(f"{len(logs)} runs ingested, {len(s.segments())} labelled segments ({how})", flush=True)
    return folder


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("how", nargs="?", default="pieces", choices=["pieces", "runs"])
    args.add_argument("--seed", type=int, default=0)
    opts = args.parse_args()
    if not DATA.is_dir():
        print(f"skipped: {DATA} is absent (BorealTC is not shipped with the project)")
        return 0
    sys.path.insert(0, str(ROOT))
    from sessions import Session
    from training import estimate_headline
    from workbench.cli import main as workbench
    from workbench.evaluation import evaluate_session
    from workbench.export import export_all

    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        folder = labelled_session(Path(tmp) / "s", opts.how, opts.seed)
        with contextlib.redirect_stdout(io.StringIO()):
            if workbench(["train", str(folder)]) != 0:
                raise SystemExit("workbench train failed")
        with Session.open(folder) as s:
            estimate = s.active_model("classifier").metrics.get("estimate") or {}
            print(f"the card: {estimate_headline(estimate)} (balanced {estimate.get('balanced_accuracy', 0):.1%})")
            export_all(s, Path(tmp) / "export")
            card = (Path(tmp) / "export" / "bundle" / "MODEL_CARD.md").read_text()
            print(next((x for x in card.splitlines() if "logs with no label" in x), "the card: no log without a label"))
            print(next((x for x in card.splitlines() if "agree with the most predicted" in x), "no agreement line"))
            report = evaluate_session(s, seed=opts.seed, log=lambda _: None)
        print(report)
        held = re.search(r"\*\*Accuracy ([\d.]+) %", report)
        if held and estimate.get("accuracy") is not None:
            gap = 100 * estimate["accuracy"] - float(held[1])
            print(f"card minus evaluate session: {gap:+.1f} points (target within 5)")
    print(f"{time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
