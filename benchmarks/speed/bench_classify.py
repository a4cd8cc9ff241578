"""``workbench classify`` of a 1-hour log, and ``workbench --help``: whole commands, start-up included.

- **classify**: one demo walk of 60 minutes written as ROS 2 MCAP (IMU at 100 Hz, four feet at 50 Hz, the camera at
  5 Hz: 22 channels aligned at 100 Hz, 360,000 steps), classified by a bundle exported from a session trained on a
  5-minute walk (stage 1 at the paper's width, hidden 200; stage 2 the default family). Wall time of the command in a
  fresh process, best of 2, beside reading the same file alone (``workbench ingest --dry-run``: parse and align, no
  model, no camera frames, as classify reads it) in the same run.
- **--help**: ``workbench --help`` beside ``python -c pass`` (the interpreter's own start-up), best of 5.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from speed_common import Row, fmt_s, parse_args, record

from sessions import Session
from training import TrainConfig
from workbench import cycle
from workbench.demo import TERRAINS, generate_walk, write_walk
from workbench.export import export_all

WORKBENCH = [sys.executable, "-m", "workbench.cli"]


def wall(cmd: list[str], *, repeat: int) -> float:
    """Best wall time of ``cmd`` over ``repeat`` runs (each a fresh process)."""
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        best = min(best, time.perf_counter() - t)
    return best


def main() -> None:
    args = parse_args(__doc__)
    minutes = 5.0 if args.quick else 60.0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t = time.perf_counter()
        log = write_walk(generate_walk(7, minutes * 60.0), folder / "hour.mcap", seed=7)
        train_log = write_walk(generate_walk(8, 300.0), folder / "train" / "walk.mcap", seed=8)
        with Session.create(folder / "s") as s:
            for name in TERRAINS:  # a new session has none
                s.add_terrain(name)
            s.ingest([train_log])
            for a, b, terrain in s.reference(s.logs()[0].id)[::3]:  # a third of the patches labelled
                s.add_segment(s.logs()[0].id, a, b, terrain, author="bench", source="manual")
            cycle.train_predictor(s, config=TrainConfig(max_epochs=1, patience=1), hidden=200)
            cycle.train_classifier(s, hidden=200)
            export_all(s, folder / "model")
        print(f"setup {time.perf_counter() - t:.0f} s", flush=True)
        out = folder / "predictions.parquet"
        bundle = str(folder / "model" / "bundle")
        classify = wall([*WORKBENCH, "classify", bundle, str(log), "--out", str(out)], repeat=2)
        # classify decodes no camera frames: neither does the reference
        dry_run = [*WORKBENCH, "ingest", str(folder / "scratch"), str(log), "--dry-run", "--camera-fps", "0"]
        read = wall(dry_run, repeat=2)
        steps = round(minutes * 60 * 100)
        rows.append(
            Row(
                f"workbench classify of a {minutes:g}-minute log (22 channels, 100 Hz, {steps:,} steps), start-up "
                "included",
                fmt_s(classify),
                f"reading the same file alone (ingest --dry-run): {fmt_s(read)}",
                f"{classify / read:.1f}× the read",
                "≤ 15 s for 1 hour",
                classify <= 15.0 if minutes == 60.0 else None,
            )
        )
    help_s = wall([*WORKBENCH, "--help"], repeat=5)
    bare = wall([sys.executable, "-c", "pass"], repeat=5)
    rows.append(
        Row(
            "workbench --help, start-up included",
            fmt_s(help_s),
            f"python -c pass: {fmt_s(bare)}",
            f"{help_s / bare:.1f}× the bare interpreter",
            "≤ 1 s",
            help_s <= 1.0,
        )
    )
    record("classify", rows, device=args.device)


if __name__ == "__main__":
    main()
