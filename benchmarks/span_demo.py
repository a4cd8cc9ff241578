"""Issue 54: what a longer span costs where terrain changes: `workbench train --span` on demo walks, then
`workbench classify` on new walks whose terrain changes every 20 s or so, scored against their truth, over all time
and over the first 2 s after each change.

    python benchmarks/span_demo.py [SPAN ...]

The model: `workbench demo --no-serve --logs 4 --minutes 3 --seed-labels 0.35` (four walks, 35 % labelled from
their truth), its classifier trained again at each span and exported; four new walks of 3 minutes (seeds 20-23).
About 5 minutes on 2 cores.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
AFTER_S = 2.0  # the time after a change scored apart


def main(spans: list[float]) -> int:
    sys.path.insert(0, str(ROOT))
    from sessions import IngestOptions
    from workbench.demo import generate_walk, write_walk
    from workbench.export import classify_files

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        cli = [sys.executable, "-m", "workbench.cli"]
        demo = ["demo", "--session", str(root / "s"), "--no-serve", "--logs", "4", "--minutes", "3"]
        subprocess.run([*cli, *demo, "--seed-labels", "0.35"], check=True, capture_output=True)
        walks = {f"new{i}": generate_walk(20 + i, 180.0) for i in range(4)}
        files = [write_walk(w, root / f"{k}.mcap", camera=False) for k, w in walks.items()]
        patches = [b - a for w in walks.values() for a, b, _ in w.truth]
        print(f"{len(walks)} new walks, {len(patches)} terrain patches, {np.mean(patches):.1f} s on average")
        print("| span | accuracy | in the 2 s after a change | elsewhere |\n| --- | --- | --- | --- |")
        for span in spans:
            train = [*cli, "train", str(root / "s"), "--stage", "classifier", "--model", "default", "--span", str(span)]
            subprocess.run(train, check=True, capture_output=True)
            out = root / f"x{span}"
            subprocess.run([*cli, "export", str(root / "s"), "--out", str(out)], check=True, capture_output=True)
            classify_files(out / "bundle", files, root / "p.csv", IngestOptions())
            pred = pd.read_csv(root / "p.csv")
            right, near = [], []
            for name, walk in walks.items():
                p = pred[pred.log == name]
                t, truth = p.t_s.to_numpy(), np.full(len(p), None, object)
                since = np.full(len(p), np.inf)
                for a, b, terrain in walk.truth:
                    inside = (t >= a) & (t < b)
                    truth[inside] = terrain
                    since[inside] = t[inside] - a if a > walk.truth[0][0] else np.inf  # a walk's start: no change
                known = truth != None  # noqa: E711 (elementwise)
                right.append(p.terrain.to_numpy()[known] == truth[known])
                near.append(since[known] < AFTER_S)
            r, n = np.concatenate(right), np.concatenate(near)
            print(f"| {span:g} s | {r.mean():.1%} | {r[n].mean():.1%} | {r[~n].mean():.1%} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main([float(s) for s in sys.argv[1:]] or [1.6, 3.4]))
