"""Kept: the per-stretch figure on files whose terrain changes (stretches under 10 s merged; 20 s merged real changes,
and 38 % of walks fell 10 points under the truth) (benchmarks/results/raw/estimates/expected-walks-2026-11-27.txt).

The per-stretch figure on files whose terrain changes: a model of four demo walks (35 % of their time labelled)
classifies new demo walks (a terrain patch every 5-36 s), and each walk's figure by stretches, at each shortest
stretch, is set against the accuracy it scored on its truth file. The other side of ``expected_borealtc.py``, where
each run is one terrain and a coarser cut can only help.

    python benchmarks/studies/expected_walks.py [--walks N] [--screen-stretch S ...]

About 2 minutes on 2 cores. Needs no dataset.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from study_common import classified_walks

import labeling
from sessions import IngestOptions, Session
from workbench import cycle
from workbench.demo import generate_demo_logs, seed_labels
from workbench.expectations import SHORTEST_STRETCH_S
from workbench.export import classify_files, export_all

WITHIN = 0.10


def main() -> int:
    args = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    args.add_argument("--walks", type=int, default=8, help="new walks to classify")
    args.add_argument("--screen-stretch", type=float, nargs="*", default=[0.0, 5.0, 20.0, 40.0])
    opts = args.parse_args()
    shortest = [SHORTEST_STRETCH_S, *(s for s in opts.screen_stretch if s != SHORTEST_STRETCH_S)]
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        s = Session.create(root / "s")
        s.ingest(generate_demo_logs(root / "logs", n_logs=4, minutes=3.0, seed=0))
        for name in sorted({t for x in s.logs() for _, _, t in s.reference(x.id)} - {t.name for t in s.terrains()}):
            s.add_terrain(name)
        seed_labels(s, 0.35, seed=1)
        cycle.train_stage1(s)
        card = cycle.train_classifier(s).metrics["estimate"]["accuracy"]
        list(export_all(s, root / "E"))
        files = generate_demo_logs(root / "new", n_logs=opts.walks, minutes=3.0, seed=77)
        new = Session.create(root / "n")
        new.ingest(files)
        code, _ = classify_files(root / "E" / "bundle", files, root / "p.csv", IngestOptions())
        assert code == 0
        print(f"model of 4 demo walks: card {card:.0%}; {opts.walks} new walks")
        truth_acc, figures = [], []
        for log, predicted, truth in classified_walks(new, root / "p.csv"):
            known = truth != -1
            truth_acc.append(float((predicted == truth)[known].mean()))
            points = cycle.log_change_points(np.asarray(new.array(log.id)), None, rate_hz=log.rate_hz)
            figures.append(
                [
                    labeling.stretch_agreement(
                        predicted, labeling.coarser_points(points, log.n_samples, round(x * log.rate_hz))
                    )
                    for x in shortest
                ]
            )
            shown = ", ".join(f"{f:.0%} at {x:g} s" for x, f in zip(shortest, figures[-1], strict=True))
            print(f"{log.name}: scored {truth_acc[-1]:.1%}; by its stretches {shown}")
        acc, fig = np.asarray(truth_acc), np.asarray(figures)
        for j, x in enumerate(shortest):
            d = fig[:, j] - acc
            print(
                f"none under {x:g} s{' (classify)' if j == 0 else ''}: within 10 points on "
                f"{np.mean(np.abs(d) <= WITHIN + 1e-9):.0%} of walks, mean error {d.mean() * 100:+.1f} points, "
                f"10 points or more under the truth on {np.mean(d <= -WITHIN):.0%}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
