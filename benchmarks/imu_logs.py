"""Logs shaped as a quadruped's body IMU as users bring them: CSV files of 6 channels (accelerometer and gyro) at
50 Hz, runs of 6 to 10 minutes, the terrains' reference in a label file beside them (for evaluation and the seeded
labels, never as labels by themselves). The signals are the demo walks' IMU (:mod:`workbench.demo.walks`), every
other sample kept, as a 50 Hz IMU driver samples it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.demo import generate_walk

IMU_RATE_HZ = 50.0
COLUMNS = ("time", "ax", "ay", "az", "wx", "wy", "wz")


def write_imu_logs(
    folder: Path, *, n_logs: int = 11, minutes: tuple[float, float] = (6.0, 10.0), seed: int = 0
) -> tuple[list[Path], Path]:
    """Write ``n_logs`` IMU CSVs of a length drawn in ``minutes`` to ``folder`` and ``reference.csv`` beside them
    (``log, terrain, start_s, end_s``); return the logs and the reference file."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    reference = ["log,terrain,start_s,end_s"]
    files = []
    for i in range(n_logs):
        walk = generate_walk(seed * 1000 + i, float(rng.uniform(*minutes)) * 60.0)
        keep = slice(None, None, 2)  # 100 Hz -> 50 Hz
        t = walk.times[keep]
        path = folder / f"quad_{i:02d}.csv"
        data = np.column_stack([t, walk.accel[keep], walk.gyro[keep]])
        np.savetxt(path, data, delimiter=",", header=",".join(COLUMNS), comments="", fmt="%.5f")
        files.append(path)
        end = float(t[-1])
        reference += [f"{path.stem},{ter},{a:.3f},{min(b, end):.3f}" for a, b, ter in walk.truth if a < end]
    ref = folder / "reference.csv"
    ref.write_text("\n".join(reference) + "\n")
    return files, ref
