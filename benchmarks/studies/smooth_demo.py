"""Kept as an option, off by default: `classify --smooth` gained +0.4 to +0.5 points on new demo walks
(benchmarks/results/raw/protocols/notebook-model-and-card-2026-11-27.md, "The optional filter").

Issue 54's optional filter on runs with real terrain changes: `workbench classify` with and without `--smooth` on
new demo walks (patches of about 20 s), scored against their truth.

    python benchmarks/studies/smooth_demo.py

The model: `workbench demo --no-serve --logs 4 --minutes 3 --seed-labels 0.35` (four walks, 35 % labelled from
their truth), exported; four new walks of 3 minutes (seeds 20-23). About 3 minutes on 2 cores.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[2]
SMOOTH_S = (2.0, 5.0, 10.0, 20.0)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from sessions import IngestOptions
    from workbench.demo import generate_walk, write_walk
    from workbench.export import classify_files

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        cli = [sys.executable, "-m", "workbench.cli"]
        demo = ["demo", "--session", str(root / "s"), "--no-serve", "--logs", "4", "--minutes", "3"]
        subprocess.run([*cli, *demo, "--seed-labels", "0.35"], check=True, capture_output=True)
        subprocess.run([*cli, "export", str(root / "s"), "--out", str(root / "x")], check=True, capture_output=True)
        walks = {f"new{i}": generate_walk(20 + i, 180.0) for i in range(4)}
        files = [write_walk(w, root / f"{k}.mcap", camera=False) for k, w in walks.items()]

        def accuracy(csv: Path) -> list[float]:
            pred, out = pd.read_csv(csv), []
            for name, walk in walks.items():
                p = pred[pred.log == name]
                t, truth = p.t_s.to_numpy(), np.full(len(p), None, object)
                for a, b, terrain in walk.truth:
                    truth[(t >= a) & (t < b)] = terrain
                known = truth != None  # noqa: E711 (elementwise)
                out.append(float(np.mean(p.terrain.to_numpy()[known] == truth[known])))
            return out

        patches = [b - a for w in walks.values() for a, b, _ in w.truth]
        print(f"{len(walks)} new walks, {len(patches)} terrain patches, {np.mean(patches):.1f} s on average")
        classify_files(root / "x" / "bundle", files, root / "raw.csv", IngestOptions())
        raw = accuracy(root / "raw.csv")
        print(f"no filter: accuracy {np.mean(raw):.1%} (per walk {', '.join(f'{a:.1%}' for a in raw)})")
        for s in SMOOTH_S:
            _, lines = classify_files(root / "x" / "bundle", files, root / "s.csv", IngestOptions(), smooth_s=s)
            delays = [x.split("change ")[1].split(" s late")[0] for x in lines if "smoothed" in x]
            acc = accuracy(root / "s.csv")
            print(
                f"--smooth {s:g}: accuracy {np.mean(acc):.1%} ({100 * (np.mean(acc) - np.mean(raw)):+.1f} points); "
                f"the causal filter's delay at each walk's median confidence: {', '.join(delays)} s"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
