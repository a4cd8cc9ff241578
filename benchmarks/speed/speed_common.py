"""What the speed rows share: timing, the row a figure is reported in, the Markdown table ``make bench`` writes, the
logs they are measured on (QCAT-shaped sequences, quadruped-IMU CSVs) and the demo-walk sessions of the Retrain rows.

Every figure is measured beside a reference run in the same process on the same data, because these machines are
shared and noisy: the ratio holds where absolute times do not. Nothing here loads PyTorch when imported: a row that
times a command's start-up runs it in a child process.
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

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmarks" / "results"
RAW_SPEED = RESULTS / "raw" / "speed"  # each bench's rows, per device, as JSON
T = TypeVar("T")
sys.path.insert(0, str(ROOT))

from sessions import LogInfo, ModelVersion, Session  # noqa: E402
from training import TrainConfig  # noqa: E402
from workbench.demo import generate_demo_logs, generate_walk  # noqa: E402


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
    """Print the rows and keep them for the table of the run (``benchmarks/results/raw/speed/<device>/<name>.json``)."""
    out = RAW_SPEED / device
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


# --- logs shaped as a quadruped's body IMU as users bring them: CSV files of 6 channels (accelerometer and gyro) at
# 50 Hz, runs of 6 to 10 minutes, the terrains' reference in a label file beside them (for evaluation and the seeded
# labels, never as labels by themselves); the demo walks' IMU, every other sample kept, as a 50 Hz IMU driver does

IMU_RATE_HZ = 50.0
COLUMNS = ("time", "ax", "ay", "az", "wx", "wy", "wz")


def free_port() -> int:
    """A TCP port free on loopback now, for a server a bench starts."""
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def wait_answering(proc, url: str, *, name: str) -> None:
    """Return once ``url`` answers 200, polling; raise with the process's output if ``proc`` exits first."""
    import urllib.request

    while True:
        if proc.poll() is not None:
            raise RuntimeError(f"{name} exited with {proc.returncode}:\n{proc.stdout.read()[-3000:]}")
        try:
            with urllib.request.urlopen(url, timeout=2) as r:
                if r.status == 200:
                    return
        except OSError:
            time.sleep(0.1)


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


# --- sessions of demo walks for the Retrain benches: labels placed as a person answering suggestions would, and the
# accuracy on every sample nobody labelled

HIDDEN = 200  # both stages: the paper's width
STAGE1 = TrainConfig(max_epochs=1, patience=1)  # stage 1 of the setup: one epoch, as in bench_retrain
SETUP_LABELS, NEW_LABELS = 40, 10  # one-second stretches: labelled before the setup's training, then after it


def walk_session(folder: Path, *, n_logs: int, minutes: float) -> tuple[Session, list[LogInfo]]:
    """A session in ``folder`` of ``n_logs`` demo walks of ``minutes`` each, their reference terrains known."""
    t = time.perf_counter()
    files = generate_demo_logs(folder / "logs", n_logs=n_logs, minutes=minutes, seed=0)
    session = Session.create(folder / "session")
    logs = session.ingest(files)
    for name in {t for x in logs for _, _, t in session.reference(x.id)} - {t.name for t in session.terrains()}:
        session.add_terrain(name)
    total = sum(x.n_samples for x in logs)
    print(
        f"{len(logs)} walks, {total:,} steps ({total / logs[0].rate_hz / 60:.0f} min), setup "
        f"{time.perf_counter() - t:.0f} s",
        flush=True,
    )
    return session, logs


def label_stretches(session: Session, rng: np.random.Generator, n: int) -> None:
    """Label ``n`` one-second stretches at random places inside reference patches, as a person answering
    suggestions does; the terrains take turns so every one is labelled."""
    patches = [(x.id, a, b, t) for x in session.logs() for a, b, t in session.reference(x.id) if b - a >= 200]
    terrains = sorted({p[3] for p in patches})
    taken = {(s.log_id, s.start) for s in session.segments()}
    for i in range(n):
        mine = [p for p in patches if p[3] == terrains[i % len(terrains)]]
        while True:
            log_id, a, b, terrain = mine[rng.integers(len(mine))]
            start = int(rng.integers(a, b - 100)) // 100 * 100
            if (log_id, start) not in taken and start + 100 <= b:
                break
        taken.add((log_id, start))
        session.add_segment(log_id, start, start + 100, terrain, author="bench", source="manual")


def unlabelled_accuracy(session: Session, scores) -> float:
    """Per-timestep accuracy of the argmax on every sample nobody labelled, against the reference terrain."""
    hits = total = 0
    segments = session.segments()  # read once, not once per log
    for x in session.logs():
        truth = np.full(x.n_samples, "", dtype=object)
        for a, b, t in session.reference(x.id):
            truth[a:b] = t
        for s in segments:
            if s.log_id == x.id:
                truth[s.start : s.stop] = ""
        pred = np.asarray(scores.classes, dtype=object)[scores.scores[x.id].probs.argmax(axis=1)]
        keep = truth != ""
        hits += int((pred[keep] == truth[keep]).sum())
        total += int(keep.sum())
    return hits / max(total, 1)


def labelled_after_training(
    session: Session, rng: np.random.Generator, *, model: str, config: TrainConfig | None = None
) -> ModelVersion:
    """What a person did before pressing Retrain: ``SETUP_LABELS`` labels, both stages trained (stage 2 of family
    ``model``), then ``NEW_LABELS`` more labels. Returns the setup's classifier version."""
    from workbench import cycle  # loads PyTorch: only where a row trains

    label_stretches(session, rng, SETUP_LABELS)
    t = time.perf_counter()
    cycle.train_predictor(session, config=STAGE1, hidden=HIDDEN)
    setup = cycle.train_classifier(session, model=model, config=config, hidden=HIDDEN)
    print(f"setup models {time.perf_counter() - t:.0f} s", flush=True)
    label_stretches(session, rng, NEW_LABELS)
    return setup
