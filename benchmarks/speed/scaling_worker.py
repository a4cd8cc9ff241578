"""One process of ``bench_scaling``: stage 1 on ``.npy`` logs read a batch at a time, in this process or as one rank
of a ``torchrun`` group. The main process prints one JSON line: seconds, real timesteps per epoch, loss history and
every process's peak resident memory.

Usage: ``[torchrun --nproc-per-node N] scaling_worker.py FOLDER EPOCHS HIDDEN THREADS BATCH``
"""

from __future__ import annotations

import json
import os
import resource
import sys
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from sessions import FileRows  # noqa: E402
from training import TrainConfig, distributed, fit_predictor  # noqa: E402


def main() -> None:
    folder, epochs, hidden = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    torch.set_num_threads(int(sys.argv[4]))
    world = distributed.join("cpu")
    rows = [FileRows.open_npy(f) for f in sorted(folder.glob("*.npy"))]
    config = TrainConfig(max_epochs=epochs, patience=epochs + 1, batch_size=int(sys.argv[5]))
    distributed.barrier()
    t = time.perf_counter()
    fit = fit_predictor(rows, config=config, hidden=hidden)
    seconds = time.perf_counter() - t
    rss = [0.0] * world.size
    rss[world.rank] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6  # kB -> GB
    rss = distributed.all_sum(rss)
    if world.main:
        print(
            json.dumps(
                {
                    "seconds": seconds,
                    "timesteps": fit.timesteps,
                    "epochs": len(fit.history),
                    "history": fit.history,
                    "rss_gb": rss,
                    "processes": world.size,
                    "threads": torch.get_num_threads(),
                    "logs": len(rows),
                }
            )
        )
    distributed.leave()
    sys.stdout.flush()
    # now and then a process aborts in the interpreter's teardown after the group is left ("terminate called
    # without an active exception", a gloo thread; it failed one `make bench` here): the result is printed, so
    # this worker skips the teardown
    os._exit(0)


if __name__ == "__main__":
    main()
