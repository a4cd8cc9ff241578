"""Self-training's units (``WindowFitConfig.unit_agree``) where terrain changes: a model of four demo walks
(a share of their time labelled in 3 s pieces) with each unlabelled stretch judged alone (``unit_agree`` 0, the
default) and by the span between change points it is a piece of, then ``workbench classify`` on new demo walks
(a terrain patch every 5-36 s), scored on their truth. BorealTC's runs are one terrain each; this is the case
where a span between change points may still hold two.

    python benchmarks/units_walks.py [--walks N] [--labelled 0.1 0.35] [--seeds 1 2] [--unit-agree 0.6]

About 4 minutes on 2 cores. Needs no dataset.
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np
from walk_session import classified_walks

from sessions import IngestOptions, Session
from workbench import cycle
from workbench.demo import generate_demo_logs, seed_labels
from workbench.export import classify_files, export_all
from workbench.retrain import RETRAIN


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--walks", type=int, default=8, help="new walks to classify")
    args.add_argument("--labelled", type=float, nargs="+", default=[0.1, 0.35])
    args.add_argument("--unit-agree", type=float, default=0.6, help="the units' setting set against 0 (off)")
    args.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="seeds of the labelled pieces")
    opts = args.parse_args()
    print(f"| labelled | label seed | each stretch alone | units at {opts.unit_agree} | pseudo-labelled stretches |")
    print("| --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        files = generate_demo_logs(root / "new", n_logs=opts.walks, minutes=3.0, seed=77)
        new = Session.create(root / "n")
        new.ingest(files)
        for share in opts.labelled:
            for seed in opts.seeds:
                s = Session.create(root / f"s{share}-{seed}")
                s.ingest(generate_demo_logs(root / f"logs{share}-{seed}", n_logs=4, minutes=3.0, seed=0))
                known = {t.name for t in s.terrains()}
                for name in sorted({t for x in s.logs() for _, _, t in s.reference(x.id)} - known):
                    s.add_terrain(name)
                seed_labels(s, share, seed=seed)
                cycle.train_stage1(s)
                cells, taken = [], []
                for unit_agree in (0.0, opts.unit_agree):
                    version = cycle.train_classifier(s, window=replace(RETRAIN.window, unit_agree=unit_agree))
                    taken.append(f"{version.metrics['pseudo_stretches']:.0f}")
                    out = root / f"E{share}-{seed}-{unit_agree}"
                    list(export_all(s, out))
                    code, _ = classify_files(out / "bundle", files, root / "p.csv", IngestOptions())
                    assert code == 0
                    walks = classified_walks(new, root / "p.csv")
                    cells.append(f"{np.mean([(p == t)[t != -1].mean() for _, p, t in walks]):.1%}")
                print(f"| {share:.0%} | {seed} | {' | '.join(cells)} | {' / '.join(taken)} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
