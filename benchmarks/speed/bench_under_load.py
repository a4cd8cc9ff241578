"""Training on a busy machine (issue 53, item 3): the default family's stage 1 (the frame predictor) and stage 2 on a
session of 14 minutes of demo walks (10 % labelled), alone, beside one single-threaded busy loop and beside two, with
the threads `workbench train` now chooses for stage 1 (``training.use_free_cpus``: one per CPU free when it starts)
against torch's own choice (a thread per core whatever else runs). Stage 2 keeps torch's count (its fits run one
thread each, side by side): its rows show it against itself alone. Each fit runs in a fresh interpreter; the frames
are cached first.

The figure is the slowdown against the same fit alone. A fit that gets one core of two should take about twice as
long, not the 3.75x (one loop) and 27x (two processes) measured with torch's own threads.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from speed_common import Row, parse_args, record

BUSY = "while True: pass"


def child(args: list[str]) -> None:
    what, policy, folder = args[0], args[1], Path(args[2])
    from sessions import Session
    from workbench import cycle

    if policy == "workbench" and what == "stage1":  # as `workbench train` runs stage 1; stage 2 keeps torch's count
        from training import use_free_cpus

        use_free_cpus()
    with Session.open(folder / "session") as s:
        t = time.perf_counter()
        if what == "stage1":
            cycle.train_frame_predictor(s)
        else:
            cycle.train_classifier(s)
        seconds = time.perf_counter() - t
    import torch

    print(json.dumps({"seconds": seconds, "threads": torch.get_num_threads()}))


def setup(folder: Path, minutes: float) -> None:
    from sessions import Session
    from workbench import cycle
    from workbench.demo import TERRAINS, generate_demo_logs, seed_labels

    files = generate_demo_logs(folder / "logs", n_logs=4, minutes=minutes / 4, seed=3)
    with Session.create(folder / "session") as s:
        for name in TERRAINS:
            s.add_terrain(name)
        s.ingest(files)
        seed_labels(s, 0.10, seed=0)
        cycle.train_frame_predictor(s)  # the frames are cached: the fits below time the fits


def measure(what: str, policy: str, folder: Path, loops: int) -> tuple[float, int]:
    busy = [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(loops)]
    try:
        time.sleep(1.0)  # the loops are running when the fit counts the free CPUs
        out = subprocess.run(
            [sys.executable, __file__, "--child", what, policy, str(folder)], capture_output=True, text=True
        )
    finally:
        for p in busy:
            p.kill()
            p.wait()
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-3000:])
    got = json.loads(out.stdout.strip().splitlines()[-1])
    return float(got["seconds"]), int(got["threads"])


def main() -> None:
    args = parse_args(__doc__)
    minutes = 4.0 if args.quick else 14.0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        subprocess.run(
            [sys.executable, __file__, "--setup", str(folder), str(minutes)], check=True, capture_output=True
        )
        for what, label in (("stage1", "frame predictor (stage 1)"), ("stage2", "stage 2 (ten fits)")):
            times: dict[tuple[str, int], tuple[float, int]] = {}
            for policy in ("workbench", "torch") if what == "stage1" else ("workbench",):
                for loops in (0, 1, 2):
                    times[(policy, loops)] = measure(what, policy, folder, loops)
            if what == "stage2":  # the same threads either way
                times.update({("torch", k): v for (_, k), v in list(times.items())})
            alone = times[("workbench", 0)][0]
            for loops in (1, 2):
                ours, threads = times[("workbench", loops)]
                theirs = times.get(("torch", loops), (float("nan"), 0))[0]
                torch_alone = times[("torch", 0)][0]
                rows.append(
                    Row(
                        f"{label}, {minutes:.0f} min session, beside {loops} busy loop{'s' * (loops > 1)}: "
                        + (f"threads from the free CPUs ({threads})" if what == "stage1" else "its fits side by side"),
                        f"{ours:.1f} s ({ours / alone:.2f}× alone)",
                        f"alone {alone:.1f} s; torch's own threads: alone {torch_alone:.1f} s, beside "
                        f"{loops}: {theirs:.1f} s ({theirs / torch_alone:.2f}×)",
                        f"{ours / alone:.2f}× alone, against {theirs / torch_alone:.2f}×",
                        "≤ 2.5× alone beside one busy loop" if loops == 1 else "in proportion to the CPU it gets",
                        ours / alone <= 2.5 if loops == 1 else None,
                    )
                )
    record("under_load", rows, device=args.device)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2:])
    elif len(sys.argv) > 1 and sys.argv[1] == "--setup":
        setup(Path(sys.argv[2]), float(sys.argv[3]))
    else:
        main()
