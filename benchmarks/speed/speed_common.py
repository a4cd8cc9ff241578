"""What every benchmark shares: timing, the row a figure is reported in, and the Markdown table ``make bench`` writes.

Every figure is measured beside a reference run in the same process on the same data, because these machines are
shared and noisy: the ratio holds where absolute times do not.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
T = TypeVar("T")
sys.path.insert(0, str(ROOT))


@dataclass(frozen=True)
class Row:
    """One figure of the table.

    Attributes:
        figure: What was measured.
        value: The figure, formatted with its unit.
        reference: What it is compared with, and its value.
        ratio: How the figure compares with the reference, as the target states it (e.g. "31× faster").
        target: The target, in words.
        met: Whether the target is met (None: no target).
        accuracy: The accuracy of what was timed beside the unoptimised path's, where it applies.
    """

    figure: str
    value: str
    reference: str
    ratio: str
    target: str
    met: bool | None
    accuracy: str = ""


def parse_args(doc: str | None) -> argparse.Namespace:
    """``--device cpu|cuda`` and ``--quick`` (smaller sizes, for a smoke run) for every benchmark."""
    p = argparse.ArgumentParser(description=doc)
    p.add_argument("--device", default="cpu", choices=("cpu", "cuda"))
    p.add_argument("--quick", action="store_true", help="small sizes: checks the script runs, figures mean little")
    return p.parse_args()


def qcat_like(n_seq: int, seed: int = 0) -> list[np.ndarray]:
    """The issues' reference workload: ``n_seq`` sequences of 100–660 samples × 22 channels (forces, gyro, accel,
    quaternion), sliced from one demo walk (2,880 of them ≈ 1 M timesteps, QCAT's scale)."""
    from workbench.demo import generate_walk

    rng = np.random.default_rng(seed)
    lengths = rng.integers(100, 661, n_seq)
    walk = generate_walk(seed, float(lengths.sum()) / 100.0 + 10.0)
    x = np.concatenate([walk.forces.reshape(len(walk.times), -1), walk.gyro, walk.accel, walk.quat], 1)
    x = x.astype(np.float32)
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    return [x[a : a + n] for a, n in zip(starts, lengths, strict=True)]


def timed(fn: Callable[[], object], *, repeat: int, warmup: int = 3) -> np.ndarray:
    """Seconds per call of ``fn`` over ``repeat`` calls after ``warmup`` untimed ones: ``(repeat,)``."""
    for _ in range(warmup):
        fn()
    out = np.empty(repeat)
    for i in range(repeat):
        t = time.perf_counter()
        fn()
        out[i] = time.perf_counter() - t
    return out


def fmt_s(seconds: float) -> str:
    """A duration with a unit a person reads at a glance."""
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.1f} s"


def record(name: str, rows: list[Row], *, device: str) -> None:
    """Print the rows and keep them for the table of the run (``benchmarks/results/<device>/<name>.json``)."""
    out = RESULTS / device
    out.mkdir(parents=True, exist_ok=True)
    meta = {"machine": platform.machine(), "cpus": os.cpu_count(), "python": platform.python_version()}
    (out / f"{name}.json").write_text(json.dumps({"rows": [asdict(r) for r in rows], "meta": meta}, indent=1))
    print(table(rows))


def table(rows: list[Row]) -> str:
    """Markdown table of rows."""
    head = "| figure | value | reference (same run) | ratio | target | met | accuracy |\n" + "| --- " * 7 + "|"
    mark = {True: "yes", False: "**no**", None: "–"}
    body = [
        f"| {r.figure} | {r.value} | {r.reference} | {r.ratio} | {r.target} | {mark[r.met]} | {r.accuracy or '–'} |"
        for r in rows
    ]
    return "\n".join([head, *body])


def hosted_like_the_server(fn: Callable[[], T]) -> T:
    """Run ``fn`` in a second thread while this thread serves ``workbench.ui.torch_lane.LANE``, as ``workbench serve``
    hosts the UI: the Retrain's and the scoring's torch work then runs here. Returns what ``fn`` returned."""
    import threading

    from workbench.ui import LANE

    out: list[T] = []
    errors: list[BaseException] = []

    def target() -> None:
        try:
            out.append(fn())
        except BaseException as exc:  # raised again in this thread
            errors.append(exc)

    worker = threading.Thread(target=target, name="bench-ui")
    LANE.serve(stop=lambda: not worker.is_alive(), started=worker.start)
    worker.join()
    if errors:
        raise errors[0]
    return out[0]
