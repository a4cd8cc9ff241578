"""A fit's first networks, kept so that the next fit on the same labels starts where they ended.

Each of a fit's networks is first trained on the labels alone (most of its time), then goes on with the stretches
it pseudo-labels. The export's taught fit is the session's last fit again with other pseudo-labels over the
stretches: its first networks are the ones the session's fit trained a moment before, the same rows, classes, seeds
and settings. Kept in a folder under a digest of all of that (the rows' values themselves, not their names), a later
fit that would compute the same network reads it instead: the same weights bit for bit, so the same result, in the
time of the refits alone. A digest that matches nothing is trained as before; the folder is a cache, pruned to the
newest :data:`KEPT` networks.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import uuid
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch
from safetensors.torch import load_file, save_file

from .spectra import SpectralSteps, last_frame
from .window_classifier import WindowClassifier
from .window_config import WindowFitConfig

KEPT = 40  # networks: a fit of 5 members and 5 folds over runs keeps 10, so the last four fits are always there

Segment = tuple[int, int, int, int]


def start_key(
    features: Sequence[SpectralSteps],
    train: Sequence[Segment],
    model: WindowClassifier,
    config: WindowFitConfig,
    seed: int,
) -> str:
    """A digest of everything a network trained on ``train`` alone depends on: each segment's frames and class, the
    untrained network's weights and standardisation (so its config and initial draw), the fit's settings, the seed,
    the device and the library that trains it."""
    h = hashlib.sha256()
    settings = [asdict(config), seed, torch.__version__, model.in_mean.device.type]
    h.update(json.dumps(settings, sort_keys=True, default=str).encode())
    h.update(repr(features[0].config).encode() if features else b"")
    for i, a, b, c in train:
        steps = features[i]
        ends = last_frame(np.asarray([a, max(a, b - 1)], np.int64), steps.config)
        lo, hi = max(int(ends[0]) - steps.config.window + 1, 0), int(ends[1]) + 1
        frames = np.asarray(steps.frames[lo:hi], np.float32)  # (n, F): every frame a step of the segment reads
        h.update(np.asarray([i, a, b, c, len(steps), lo, hi], np.int64).tobytes())
        h.update(np.ascontiguousarray(frames).tobytes())
    for name, value in sorted(model.state_dict().items()):
        h.update(name.encode())
        h.update(value.detach().cpu().contiguous().numpy().tobytes())
    return h.hexdigest()[:32]


def load_start(folder: Path, key: str, model: WindowClassifier) -> WindowClassifier | None:
    """``model`` with the kept network's weights (in eval mode, as training leaves it), or ``None`` when none is
    kept under ``key`` or the file cannot be read (a cache: then it is trained again)."""
    path = folder / f"{key}.safetensors"
    if not path.is_file():
        return None
    try:
        weights = load_file(path)
        model.load_state_dict({k: v.to(model.in_mean.device) for k, v in weights.items()})
    except Exception:  # a damaged or foreign file in a cache costs its fit, never the fit
        return None
    os.utime(path)  # read: the newest in the pruning's order
    return model.eval()


def save_start(folder: Path, key: str, model: WindowClassifier) -> None:
    """Keep ``model``'s weights under ``key`` (written whole under a temporary name, then renamed) and prune the
    folder to the newest :data:`KEPT`. A disk that refuses costs nothing but the next fit's time."""
    tmp = folder / f".{key}.{uuid.uuid4().hex[:8]}.tmp"
    try:
        save_file({k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}, tmp)
        os.replace(tmp, folder / f"{key}.safetensors")
        kept = sorted(folder.glob("*.safetensors"), key=lambda p: p.stat().st_mtime, reverse=True)
        for old in kept[KEPT:]:
            old.unlink(missing_ok=True)
        for stale in folder.glob(".*.tmp"):  # a fit killed while writing: gone once it is surely not being written
            if stale.stat().st_mtime < time.time() - 3600:
                stale.unlink(missing_ok=True)
    except Exception:  # another fit pruned the same file first, or the disk is full (safetensors' own error)
        tmp.unlink(missing_ok=True)
