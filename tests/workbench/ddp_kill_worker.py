"""Run under ``torchrun`` by ``test_torchrun``: stage-1 training as ``workbench train --stage predictor`` runs it,
except that the main process kills itself with SIGKILL half-way through epoch 2 (as a power cut or the OOM killer
would) and the checkpoint is written after every batch.

Usage: ``torchrun --nproc-per-node 2 tests/workbench/ddp_kill_worker.py SESSION MAX_EPOCHS``
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

from sessions import Session
from training import TrainConfig, distributed
from workbench import cycle


def main() -> None:
    path, max_epochs = Path(sys.argv[1]), int(sys.argv[2])
    world = distributed.join("cpu")
    # what `workbench train --hidden 8 --batch-size 4 --max-epochs N --patience N` builds, so the checkpoint is its
    config = TrainConfig(max_epochs=max_epochs, patience=max_epochs, device="cpu", batch_size=4)

    def progress(p) -> None:
        if p.epoch == 2 and p.steps // 2 <= p.step < p.steps:
            os.kill(os.getpid(), signal.SIGKILL)

    if not world.main:
        cycle.follow_predictor_training(config=config, hidden=8, checkpoint_every=1)
        return
    with Session.open(path) as s:
        cycle.train_predictor(s, config=config, hidden=8, progress=progress, checkpoint_every=1)


if __name__ == "__main__":
    main()
