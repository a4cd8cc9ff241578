"""The default family's ensemble over a log's frames: each member once per frame, its logits and its drift from one
network pass.

A step's input is the last ``window`` frames complete at or before it (:class:`.spectra.SpectralSteps`), so every
step between two frames asks the same question: at 100 Hz with a frame every 0.2 s, twenty steps in a row. The step
pass built each step's row, searched the rows for repeats and ran the members on what was left, then the drift ran
each member again on the frames for its embedding. Here each member runs once per frame and both the probabilities
and the drift come from that one pass; the caller repeats a frame's answer over its steps
(:func:`.frame_numpy.step_frames`). The same pass in NumPy, without PyTorch: :class:`.frame_numpy.NumpyMembers`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence

import numpy as np
import torch

from .frame_numpy import FrameChunk
from .spectra import SpectralSteps, window_index
from .window_classifier import WindowClassifier
from .window_drift import QUERY_CHUNK, DriftReference, views_drift, views_of


@torch.inference_mode()
def frame_chunks(
    models: Sequence[WindowClassifier],
    steps: SpectralSteps,
    *,
    drift: DriftReference | None = None,
    chunk: int = QUERY_CHUNK,
) -> Iterator[FrameChunk]:
    """Every member over every frame of one log, ``chunk`` frames at a time.

    The numbers are those of the step pass and :func:`.window_drift.drift_of_log` (the same operations; the
    standardising and the 1x1 mixing run once per frame rather than once per window holding it, so the probabilities
    and the drift may differ in the last bits where the matrix products batch rows differently).

    Args:
        models: The ``M`` members.
        steps: The log's stage-2 inputs (its frames are read a chunk at a time).
        drift: The bundle's drift reference: each frame's drift is computed from the same pooled features.
        chunk: Frames per network call.
    """
    cfg = steps.config
    n = len(steps.frames)
    device = models[0].in_mean.device
    for model in models:
        model.eval()
    for c in range(0, n, chunk):
        idx = np.arange(c, min(c + chunk, n))
        lo = max(c - cfg.window + 1, 0)
        block = torch.from_numpy(np.array(steps.frames[lo : int(idx[-1]) + 1], np.float32)).to(device)  # (b, F) a copy
        # each frame's window as indices into the block, as stacked_frames lays the rows out
        window = torch.from_numpy(window_index(idx - lo, cfg.window)).to(device)  # (n, W)
        probs = np.empty((len(models), len(idx), models[0].config.n_classes), np.float32)
        total = np.zeros(len(idx), np.float32) if drift is not None else None
        for m, model in enumerate(models):
            # standardising and the 1x1 mixing read one frame each: once per frame, not once per window it sits in
            standard = (block - model.in_mean) * model.in_scale  # (b, F)
            pooled = model.pool(model.windowed(model.mixed(standard)[window]))  # (n, 2H)
            probs[m] = torch.softmax(model.head(pooled), -1).cpu().numpy()
            if drift is not None and total is not None:  # the drift's views of the same pass; (n, W, F) its inputs'
                total += views_drift(drift, m, views_of(pooled, standard[window]))
        yield FrameChunk(c, probs, None if total is None else total / len(models))


@torch.inference_mode()
def blank_probs(models: Sequence[WindowClassifier]) -> np.ndarray:
    """``(M, K)`` each member's probabilities for a step before the log's first frame completes (its input is
    zeros, as :class:`.spectra.SpectralSteps` gives it)."""
    device = models[0].in_mean.device
    zeros = torch.zeros((1, models[0].config.n_features), device=device)  # (1, W·F)
    return np.stack([torch.softmax(m.eval().logits(zeros), -1)[0].cpu().numpy() for m in models])
