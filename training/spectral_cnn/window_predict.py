"""A window classifier's answers offline: the classes of a log's steps, the logits of frame rows, a chunk at a time
(what the fits' out-of-fold figures, the calibration and the fine-tune read)."""

from __future__ import annotations

import itertools

import numpy as np
import torch

from .spectra import SpectralSteps
from .window_classifier import WindowClassifier
from .window_rows import WindowRows

PREDICT_CHUNK = 4096  # steps per call when scoring segments: bounds the stacked frames in memory


@torch.inference_mode()
def predict_steps(model: WindowClassifier, features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """Classes of steps ``[start, stop)`` of one log, as the offline passes score them (a chunk at a time)."""
    out, dev = [], model.in_mean.device
    for c in range(start, stop, PREDICT_CHUNK):
        chunk = torch.from_numpy(features[c : min(c + PREDICT_CHUNK, stop)])[None].to(dev)  # (1, L, D)
        out.append(model(chunk)[0][0].argmax(1).cpu().numpy())
    features.release()
    return np.concatenate(out) if out else np.zeros(0, np.int64)


@torch.inference_mode()
def row_logits(model: WindowClassifier, x: np.ndarray | WindowRows) -> np.ndarray:
    """Logits ``(N, K)`` of rows ``(N, W·F)`` (stacked, or :class:`WindowRows` stacked a chunk at a time)."""
    if len(x) == 0:
        return np.zeros((0, model.config.n_classes), np.float32)
    n, big = divmod(len(x), -(-len(x) // PREDICT_CHUNK))  # np.array_split's chunks: ``big`` one row longer
    cuts = np.concatenate([[0], np.cumsum([n + 1] * big + [n] * (-(-len(x) // PREDICT_CHUNK) - big))])
    chunks = (np.asarray(x[a:b], np.float32) for a, b in itertools.pairwise(cuts))
    dev = model.in_mean.device
    return torch.cat([model.logits(torch.from_numpy(c).to(dev)).cpu() for c in chunks]).numpy()
