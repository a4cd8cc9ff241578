"""Stage-1 training on 1 and 2 processes of this machine (``torchrun``, gloo), and memory per process against the
number of logs: the figures ``docs/scaling.md`` builds on.

Logs are ``.npy`` files (QCAT-like sequences, 22 channels) read a batch at a time, as a session's are. Every run is
a fresh process (or group) training the paper's model (hidden 200, batch 512) for one epoch; each times
``fit_predictor`` alone, after its imports and after joining the process group.

Rows:
- 2 processes × 1 thread against 1 process × 1 thread (the unit being scaled) and 1 process × all threads (what one
  machine gives without torchrun): throughput in real timesteps per second, and the loss after the epoch.
- peak resident memory per process with 4× as many logs: it must not grow with the number of logs.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from speed_common import ROOT, Row, parse_args, qcat_like, record

WORKER = str(ROOT / "benchmarks" / "speed" / "scaling_worker.py")
MEM_BATCH = 64


def write_logs(folder: Path, n_seq: int, seed: int) -> Path:
    folder.mkdir(parents=True)
    for i, a in enumerate(qcat_like(n_seq, seed)):
        np.save(folder / f"{i:05d}.npy", a)
    return folder


def train(folder: Path, *, procs: int, threads: int, epochs: int = 1, hidden: int = 200, batch: int = 512) -> dict:
    args = [WORKER, str(folder), str(epochs), str(hidden), str(threads), str(batch)]
    env = {**os.environ, "OMP_NUM_THREADS": str(threads)}
    if procs > 1:
        cmd = [
            sys.executable,
            "-m",
            "torch.distributed.run",
            f"--nproc-per-node={procs}",
            "--master-addr=127.0.0.1",
            "--master-port=29533",
            *args,
        ]
    else:
        cmd = [sys.executable, *args]
    out = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
    if out.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{out.stderr[-3000:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    print(
        f"{procs} process(es) x {threads} thread(s), batch {batch}, {result['logs']} logs: "
        f"{result['seconds']:.1f} s, "
        f"{result['timesteps'] * result['epochs'] / result['seconds']:,.0f} steps/s, "
        f"peak RSS {', '.join(f'{g:.2f}' for g in result['rss_gb'])} GB"
    )
    return result


def rate(r: dict) -> float:
    return r["timesteps"] * r["epochs"] / r["seconds"]


def main() -> None:
    args = parse_args(__doc__)
    if args.device != "cpu":
        print("bench_scaling measures CPU processes (gloo); on a GPU machine see docs/scaling.md")
        return
    n_seq = 288 if args.quick else 2880
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        logs = write_logs(Path(tmp) / "logs", n_seq, seed=0)
        one_1 = train(logs, procs=1, threads=1)
        one_all = train(logs, procs=1, threads=cores)
        two_1 = train(logs, procs=2, threads=1)
        # batch 64 for the memory pair: each process's share of both sets then fills several training batches and
        # at least one validation batch, where the peak is (the whole padded length in one call), so the pair
        # differs in the number of logs only (at batch 128 the small set's validation batch was part-full)
        small = write_logs(Path(tmp) / "quarter", n_seq // 4, seed=1)
        mem_small = train(small, procs=2, threads=1, batch=MEM_BATCH)
        mem_big = train(logs, procs=2, threads=1, batch=MEM_BATCH)
    loss = (
        f"train MSE after the epoch: 1 process {one_1['history'][-1]['train_loss']:.4f}, "
        f"2 processes {two_1['history'][-1]['train_loss']:.4f} (same global batch and seed)"
    )
    speedup = rate(two_1) / rate(one_1)
    rows = [
        Row(
            f"stage-1 training, 2 processes x 1 thread (torchrun, gloo), hidden 200, batch 512, {n_seq} sequences",
            f"{rate(two_1):,.0f} steps/s",
            f"1 process x 1 thread: {rate(one_1):,.0f} steps/s; 1 process x {cores} threads: {rate(one_all):,.0f}",
            f"{speedup:.2f}× one process (scaling efficiency {speedup / 2:.0%}); "
            f"{rate(two_1) / rate(one_all):.2f}× one process with all {cores} threads",
            "measured, for docs/scaling.md",
            None,
            loss,
        ),
        Row(
            f"peak memory per training process, 2 processes, batch {MEM_BATCH}, against the number of logs",
            f"{max(mem_big['rss_gb']):.2f} GB with {mem_big['logs']} logs",
            f"{max(mem_small['rss_gb']):.2f} GB with {mem_small['logs']} logs",
            f"{max(mem_big['rss_gb']) / max(mem_small['rss_gb']):.2f}× with 4× the logs",
            "not growing with the number of logs",
            bool(max(mem_big["rss_gb"]) < 1.1 * max(mem_small["rss_gb"])),
            f"batch 512: {max(two_1['rss_gb']):.2f} GB per process with 2 processes, "
            f"{max(one_all['rss_gb']):.2f} GB with 1",
        ),
    ]
    record("scaling", rows, device=args.device)


if __name__ == "__main__":
    main()
