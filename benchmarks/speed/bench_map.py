"""The page's map on 10 hours of logs: its first draw and the marker following the cursor.

A session of 20 runs of 30 minutes (6-channel IMU CSVs at 50 Hz with a GNSS fix in every row, one field: every run
in one frame, so the map of one run draws the other 19 under it). Timed on the server, as the page's ``MapView``
does it, against a recording scene (what would be sent to the browser is built, nothing is sent):

- the first draw (**M**): every run's track read and coloured, the log's path, its labels, the other runs, the
  scale and the marker; reference: reading every run's tracks alone (``Session.poses``), the least a map can do.
- the marker: ``MapView.update`` after the cursor moved (the key check, a query of the log's labels, the marker's
  position); reference: the same query of the log's labels alone.

The browser's own drawing (three.js, at most 5,000 segments of the log and 1,000 of each other run) is not timed.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
from speed_common import Row, fmt_s, parse_args, record

from sessions import Session

RATE = 50.0


class _Scene:
    """viser's scene as the map uses it, recording instead of sending."""

    def __init__(self) -> None:
        self.segments = 0

    def on_click(self):
        return lambda fn: fn

    def _add(self, name: str, *args, **kwargs) -> SimpleNamespace:
        if args and hasattr(args[0], "shape"):
            self.segments += len(args[0])
        return SimpleNamespace(visible=True, position=None, remove=lambda: None)

    add_line_segments = add_label = add_icosphere = _add


def write_runs(folder: Path, *, n_runs: int, minutes: float) -> list[Path]:
    """``n_runs`` CSVs of a walk around one field with an IMU and a GNSS fix per row."""
    folder.mkdir(parents=True)
    files = []
    for k in range(n_runs):
        rng = np.random.default_rng(k)
        t = np.arange(int(minutes * 60 * RATE)) / RATE
        angle = 2 * np.pi * t / 300.0 + k  # a loop of 50 m every 5 minutes, each run turned
        frame = pd.DataFrame({"time": t})
        for c in ("ax", "ay", "az", "gx", "gy", "gz"):
            frame[c] = rng.normal(size=len(t)).astype(np.float32)
        frame["lat"] = 45.38 + (25 * np.sin(angle) + rng.normal(0, 0.1, len(t))) / 111_195.0
        frame["lon"] = -71.92 + (25 * np.cos(angle) + rng.normal(0, 0.1, len(t))) / 78_200.0
        path = folder / f"run_{k:02d}.csv"
        frame.to_csv(path, index=False, float_format="%.7f")
        files.append(path)
    return files


def main() -> None:
    from workbench.ui import MapView

    args = parse_args(__doc__)
    n_runs, minutes = (4, 5.0) if args.quick else (20, 30.0)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        files = write_runs(Path(tmp) / "logs", n_runs=n_runs, minutes=minutes)
        s = Session.create(Path(tmp) / "s")
        logs = s.ingest(files)
        s.add_terrain("grass")
        for x in logs:  # a fifth of every run labelled
            s.add_segment(log_id=x.id, start=0, stop=x.n_samples // 5, terrain="grass", author="bench")
        hours = sum(x.n_samples for x in logs) / RATE / 3600
        print(f"set-up: {n_runs} runs, {hours:.1f} h, {time.perf_counter() - t0:.0f} s", flush=True)

        def reference() -> float:
            t = time.perf_counter()
            for x in logs:
                s.poses(x.id)
            return time.perf_counter() - t

        def first_draw() -> tuple[float, int]:
            scene = _Scene()
            host = SimpleNamespace(
                client=SimpleNamespace(
                    scene=scene, camera=SimpleNamespace(position=(3.0, 3.0, 3.0), look_at=(0, 0, 0))
                ),
                state=SimpleNamespace(session=s, scores=SimpleNamespace(scores={}, classes=())),
                log=logs[0],
                cursor_s=0.0,
                guard=lambda fn: fn(),
                move_cursor=lambda seconds: None,
            )
            view = MapView(host, robot_nodes=[])
            t = time.perf_counter()
            view.toggle()
            return time.perf_counter() - t, scene.segments, view, host

        refs = [reference() for _ in range(3)]
        draws = [first_draw() for _ in range(3)]
        ref, draw = statistics.median(refs), statistics.median(d[0] for d in draws)
        _, segments, view, host = draws[-1]
        moves, queries = [], []
        rng = np.random.default_rng(0)
        for _ in range(50):
            host.cursor_s = float(rng.uniform(0, logs[0].n_samples / RATE))
            t = time.perf_counter()
            view.update()
            moves.append(time.perf_counter() - t)
            t = time.perf_counter()
            s.segments(logs[0].id)
            queries.append(time.perf_counter() - t)
        move, query = statistics.median(moves), statistics.median(queries)
        s.close()
    shape = f"{n_runs} runs of {minutes:g} min ({hours:.1f} h, 50 Hz, a GNSS fix every row, one field)"
    record(
        "map",
        [
            Row(
                f"the page's map, first draw (M) on the server, {shape}: {segments:,} segments built",
                fmt_s(draw),
                f"reading every run's tracks alone: {fmt_s(ref)}",
                f"{draw / ref:.1f}× the read",
                "≤ 2 s",
                bool(draw <= 2.0),
                "the browser's drawing not timed",
            ),
            Row(
                f"the page's map, the marker following the cursor (median of 50 moves), {shape}",
                fmt_s(move),
                f"the query of the log's labels alone: {fmt_s(query)}",
                f"{move / query:.1f}× the query",
                "≤ 50 ms",
                bool(move <= 0.05),
            ),
        ],
        device=args.device,
    )


if __name__ == "__main__":
    main()
