"""The label-efficiency simulation's stage 1 and spectral inputs for the default family: every log's frames as a
session caches them, and its own next-frame predictor as ``workbench train`` fits it (no labels), read per step."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from training import (
    FrameOutputs,
    FramePredictorConfig,
    FramePredictorFit,
    Normalizer,
    SpectralConfig,
    SpectralSteps,
    fit_frame_predictor,
    frame_surprise,
    log_frames,
)


def log_spectra(logs: Sequence[np.ndarray], normalizer: Normalizer, rate_hz: float) -> list[SpectralSteps]:
    """Every log's per-step spectral inputs, as a session caches them (computed once per simulation)."""
    front = SpectralConfig.for_log(np.concatenate(list(logs[:5])), rate_hz)
    return [SpectralSteps(log_frames(x, front, transform=normalizer), len(x), front) for x in logs]


def frame_stage1(
    train: Sequence[np.ndarray],
    pieces: Sequence[SpectralSteps],
    front: SpectralConfig,
    *,
    steps: int = FramePredictorFit.steps,
) -> tuple[list[np.ndarray], list]:
    """The default family's own stage 1, as ``workbench train`` fits it: the next-frame predictor on the frames of
    every log (``train``, no labels); then per piece (a log, or a stretch of one read from a fresh start) its
    per-step surprise ``(T,)`` and embedding ``(T, H)``; ``steps``: the fit's budget (``FramePredictorFit.steps``)."""
    fit = FramePredictorFit(steps=steps)
    model, _ = fit_frame_predictor(list(train), config=FramePredictorConfig(front.width), fit=fit)
    outs = [FrameOutputs(*frame_surprise(model, s.frames), len(s), front) for s in pieces]
    return [o.surprise() for o in outs], [o.embedding() for o in outs]


def unit_spectra(
    parts: Sequence[np.ndarray],
    units: Sequence[tuple[int, int, int]],
    normalizer: Normalizer,
    rate_hz: float,
    cache: dict,
) -> SpectralConfig:
    """The front end of BorealTC's partitions and, in ``cache["units"]``, the spectral inputs of each pool piece
    (``(partition, start, stop)``), computed once per simulation."""
    if "front" not in cache:
        front = SpectralConfig.for_log(np.concatenate(parts[:50]), rate_hz)
        cache["front"] = front
        cache["units"] = [
            SpectralSteps(log_frames(parts[i][a:b], front, transform=normalizer), b - a, front) for i, a, b in units
        ]
    return cache["front"]
