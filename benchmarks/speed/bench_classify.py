"""``workbench classify`` of a 1-hour log, and ``workbench --help``: whole commands, start-up included.

- **classify**: one demo walk of 60 minutes written as ROS 2 MCAP (IMU at 100 Hz, four feet at 50 Hz, the camera at
  5 Hz: 22 channels aligned at 100 Hz, 360,000 steps), classified by a bundle exported from a session trained on a
  5-minute walk (stage 1 at the paper's width, hidden 200; stage 2 the default family). Wall time of the command in a
  fresh process, best of 2, beside reading the same file alone (``workbench ingest --dry-run``: parse and align, no
  model, no camera frames, as classify reads it) in the same run.
- **classify of a 10-minute IMU run**: a quadruped-shaped CSV (6 channels at 50 Hz, ``speed_common.write_imu_logs``)
  classified by a bundle of a session of three such runs trained by ``workbench train`` (the default family, 10 % of
  the time labelled), beside ``ingest --dry-run`` of the same file: what a new user tries first, start-up included.
- **four runs at once**: four such runs in one ``classify``, each read and scored in a process of its own (one per
  core, the default), beside the same command with ``--jobs 1``.
- **--help**: ``workbench --help`` beside ``python -c pass`` (the interpreter's own start-up), best of 5.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

from speed_common import Row, fmt_s, parse_args, record, write_imu_logs

from sessions import Session
from training import TrainConfig
from workbench import cycle
from workbench.demo import TERRAINS, generate_walk, seed_labels, write_walk
from workbench.export import default_jobs, export_all

WORKBENCH = [sys.executable, "-m", "workbench.cli"]


def wall(cmd: list[str], *, repeat: int, clear: Path | None = None) -> float:
    """Best wall time of ``cmd`` over ``repeat`` runs (each a fresh process); ``clear``: a file the command writes,
    removed before each run (classify refuses to overwrite its output)."""
    best = float("inf")
    for _ in range(repeat):
        if clear is not None:
            clear.unlink(missing_ok=True)
        t = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True)
        best = min(best, time.perf_counter() - t)
        if done.returncode != 0:
            raise SystemExit(
                f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr.strip() or done.stdout.strip()}"
            )
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
        classify = wall([*WORKBENCH, "classify", bundle, str(log), "--out", str(out)], repeat=2, clear=out)
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
                "≤ 1.5× the read",
                classify <= 1.5 * read if minutes == 60.0 else None,
            )
        )
        rows += _imu_runs(folder / "imu", quick=args.quick)
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


def _imu_runs(folder: Path, *, quick: bool) -> list[Row]:
    """``classify`` of one IMU run (6 channels, 50 Hz CSV) beside reading it, with a bundle trained on three others;
    and of four such runs at once, a process per core (the default), beside the same command with ``--jobs 1``."""
    minutes = 2.0 if quick else 10.0
    files, reference = write_imu_logs(folder / "logs", n_logs=3, minutes=(5.0, 6.0), seed=3)
    (run,), _ = write_imu_logs(folder / "new", n_logs=1, minutes=(minutes, minutes), seed=4)
    fleet, _ = write_imu_logs(folder / "fleet", n_logs=4, minutes=(minutes, minutes), seed=5)
    with Session.create(folder / "s") as s:
        s.ingest(files)
        s.import_reference(reference, create_terrains=True)
        seed_labels(s, 0.10, seed=0, segment_s=5.0)
    subprocess.run([*WORKBENCH, "train", str(folder / "s")], check=True, capture_output=True)
    subprocess.run(
        [*WORKBENCH, "export", str(folder / "s"), "--out", str(folder / "model")], check=True, capture_output=True
    )
    bundle, out = str(folder / "model" / "bundle"), folder / "predictions.csv"
    classify = wall([*WORKBENCH, "classify", bundle, str(run), "--out", str(out)], repeat=3, clear=out)
    read = wall([*WORKBENCH, "ingest", str(folder / "scratch"), str(run), "--dry-run"], repeat=3)
    many = [*WORKBENCH, "classify", bundle, *map(str, fleet), "--out", str(out)]
    cores = wall(many, repeat=2, clear=out)
    one = wall([*many, "--jobs", "1"], repeat=2, clear=out)
    return [
        Row(
            f"workbench classify of a {minutes:g}-minute IMU run (6 channels, 50 Hz CSV), start-up included",
            fmt_s(classify),
            f"reading the same file alone (ingest --dry-run): {fmt_s(read)}",
            f"{classify / read:.1f}× the read",
            "≤ 2× the read",
            classify <= 2.0 * read if not quick else None,
        ),
        Row(
            f"workbench classify of four {minutes:g}-minute IMU runs, a process per core ({default_jobs(4)})",
            fmt_s(cores),
            f"the same with --jobs 1: {fmt_s(one)}",
            f"{one / cores:.2f}× faster",
            "faster than one process where there are two cores or more",
            cores < one if default_jobs(4) > 1 and not quick else None,
        ),
    ]


if __name__ == "__main__":
    main()
