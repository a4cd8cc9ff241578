"""The UI's torch work on one thread (``workbench.ui.torch_lane``) against the way it was hosted before: the Retrain in
its job thread and the scoring in the refresh worker, each running torch in its own thread.

Two rows, each hosting measured in a fresh process (libgomp's thread pools live as long as the threads that made
them, so the two must not share one):

- **A 2-layer LSTM (hidden 64) over 20,000 steps**: on the main thread (the reference), on a second thread while a
  thread that ran torch before is alive (the old hosting), and handed to the main thread through the lane.
- **The UI's Retrain** on a demo session (4 walks of 3 minutes, default family, tiny stage 1): Retrain pressed → the
  classifier trained and every log rescored, with ``TrainJob`` and ``SharedState`` as the page runs them; the
  session's models were trained on the main thread first, as ``workbench demo`` does. Old hosting: no lane (each
  thread runs its own torch). Lane: the main thread serves it, as ``workbench serve`` now does.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from speed_common import Row, fmt_s, parse_args, record

STEPS = 20_000


def _lstm_timer():
    import torch

    torch.manual_seed(0)
    lstm = torch.nn.LSTM(22, 64, 2, batch_first=True)
    x = torch.randn(1, STEPS, 22)  # (B, T, C)

    def once() -> float:
        best = float("inf")
        with torch.no_grad():
            for _ in range(3):
                t = time.perf_counter()
                lstm(x)
                best = min(best, time.perf_counter() - t)
        return best

    return once


def child_lstm(mode: str) -> float:
    """Seconds of the LSTM forward in one process, hosted as ``mode`` says."""
    from workbench.ui import LANE

    once = _lstm_timer()
    if mode == "main":
        return once()
    once()  # this thread has run torch: its pool stays alive, as the server's first torch thread's did
    out: list[float] = []
    if mode == "old":
        holder = threading.Event()
        other = threading.Thread(target=lambda: (once(), holder.wait()))  # e.g. the scoring worker, alive
        other.start()
        time.sleep(0.5)
        t = threading.Thread(target=lambda: out.append(once()))  # e.g. the Retrain's job thread
        t.start()
        t.join()
        holder.set()
        other.join()
        return out[0]
    t = threading.Thread(target=lambda: out.append(LANE.run(once)))  # the job thread hands its work to the lane
    LANE.serve(stop=lambda: bool(out), started=t.start)
    t.join()
    return out[0]


def child_retrain(mode: str, root: Path) -> float:
    """Seconds from Retrain pressed to every log rescored, hosted as ``mode`` says."""
    from sessions import Session
    from training import TrainConfig
    from workbench import cycle
    from workbench.demo import TERRAINS, generate_demo_logs, seed_labels
    from workbench.ui import LANE, SharedState, TrainJob

    logs = generate_demo_logs(root / "logs", n_logs=4, minutes=3.0, seed=2)
    s = Session.create(root / "s")
    for name in TERRAINS:  # a new session has none
        s.add_terrain(name)
    s.ingest(logs)
    seed_labels(s, 0.05, seed=0, segment_s=1.0)
    cycle.train_predictor(s, config=TrainConfig(max_epochs=2, piece=256), hidden=16)
    cycle.train_classifier(s, hidden=16)  # on the main thread, as workbench demo trains before it serves
    seed_labels(s, 0.03, seed=1, segment_s=1.0)  # a few more labels, then Retrain
    if mode == "lane":
        LANE.expect()
    state = SharedState(s)
    job = TrainJob(state, hidden=16, refine=False)
    took: list[float] = []

    def press() -> None:
        deadline = time.monotonic() + 600
        while not (state.scored and not state.busy) and time.monotonic() < deadline:
            time.sleep(0.05)
        started = time.monotonic()
        before = state.scores
        job.start()
        while job.running or state.scores is before or state.busy:
            time.sleep(0.02)
        took.append(time.monotonic() - started)

    presser = threading.Thread(target=press)
    if mode == "lane":
        LANE.serve(stop=lambda: not presser.is_alive(), started=presser.start)
    else:
        presser.start()
    presser.join()
    state.stop()
    s.close()
    return took[0]


def measure(what: str, mode: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [sys.executable, __file__, "--child", what, mode, tmp], capture_output=True, text=True, check=True
        )
    return float(json.loads(out.stdout.strip().splitlines()[-1])["seconds"])


def main() -> None:
    args = parse_args(__doc__)
    rows = []
    main_s, old_s, lane_s = (measure("lstm", m) for m in ("main", "old", "lane"))
    rows.append(
        Row(
            f"LSTM forward, {STEPS:,} steps, from the Retrain's thread: old hosting / through the lane",
            f"{fmt_s(old_s)} / {fmt_s(lane_s)}",
            f"main thread alone: {fmt_s(main_s)}",
            f"old {old_s / main_s:.1f}× the main thread; lane {lane_s / main_s:.2f}×",
            "lane at main-thread speed (≤ 1.5×)",
            lane_s <= 1.5 * main_s,
        )
    )
    if not args.quick:
        old_r, lane_r = (measure("retrain", m) for m in ("old", "lane"))
        rows.append(
            Row(
                "UI Retrain (default family, 4 demo walks of 3 min): pressed → every log rescored, through the lane",
                fmt_s(lane_r),
                f"old hosting (torch in the job and worker threads): {fmt_s(old_r)}",
                f"{old_r / lane_r:.1f}× faster",
                "faster than the old hosting",
                lane_r < old_r,
            )
        )
    record("torch_lane", rows, device=args.device)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        what, mode, tmp = sys.argv[2:5]
        seconds = child_lstm(mode) if what == "lstm" else child_retrain(mode, Path(tmp))
        print(json.dumps({"seconds": seconds}))
    else:
        main()
