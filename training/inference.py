"""Offline passes over whole logs: stage-1 outputs (what the feature cache holds) and ensemble probabilities.

Logs of different lengths are batched together and run in chunks with the LSTM state carried, so memory stays
bounded for hour-long logs and the result equals one pass over each whole log.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from .config import FeatureMode
from .data import Normalizer
from .models import Classifier, Predictor, stage1_features


@dataclass(frozen=True)
class Stage1Outputs:
    """Per timestep of one log, all causal at ``t``."""

    hidden: np.ndarray  # (T, H) float32: state after x_t
    error: np.ndarray  # (T, C) float32: x_t − x̂_t in normalised units (0 at t = 0)
    estimate: np.ndarray  # (T, C) float32: x̂_{t+1}, normalised

    def features(self, mode: FeatureMode) -> np.ndarray:
        """``(T, F)`` features for stage 2 in ``mode``."""
        out = stage1_features(
            mode, torch.from_numpy(self.hidden), torch.from_numpy(self.estimate), torch.from_numpy(self.error)
        )
        return out.numpy()


def _batches(lengths: Sequence[int], batch: int) -> list[list[int]]:
    order = np.argsort(lengths)[::-1]  # similar lengths together: less padding
    return [order[i : i + batch].tolist() for i in range(0, len(order), batch)]


@torch.inference_mode()
def run_predictor(
    predictor: Predictor,
    normalizer: Normalizer,
    arrays: Sequence[np.ndarray],
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> list[Stage1Outputs]:
    """Stage 1 over whole raw logs."""
    predictor = predictor.to(device).eval()
    out: list[Stage1Outputs | None] = [None] * len(arrays)
    for group in _batches([len(a) for a in arrays], batch):
        n = max(len(arrays[i]) for i in group)
        c = arrays[group[0]].shape[1]
        x = np.zeros((len(group), n, c), np.float32)
        for j, i in enumerate(group):
            x[j, : len(arrays[i])] = normalizer(arrays[i])
        xt = torch.from_numpy(x).to(device)
        hid = np.empty((len(group), n, predictor.config.hidden), np.float32)
        est = np.empty((len(group), n, c), np.float32)
        state = None
        for c0 in range(0, n, chunk):
            e, h, state = predictor(xt[:, c0 : c0 + chunk], state)  # (B, L, C), (B, L, H)
            hid[:, c0 : c0 + chunk] = h.cpu().numpy()
            est[:, c0 : c0 + chunk] = e.cpu().numpy()
        err = np.zeros_like(x)
        err[:, 1:] = x[:, 1:] - est[:, :-1]  # error of the estimate made one step earlier
        for j, i in enumerate(group):
            t = len(arrays[i])
            out[i] = Stage1Outputs(hid[j, :t].copy(), err[j, :t].copy(), est[j, :t].copy())
    return out  # type: ignore[return-value]


@torch.inference_mode()
def run_classifiers(
    models: Sequence[Classifier],
    features: Sequence[np.ndarray],
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> list[np.ndarray]:
    """Every ensemble member over whole logs' features.

    Returns:
        Per log, ``(M, T, K)`` float32 class probabilities of the ``M`` members.
    """
    out: list[np.ndarray | None] = [None] * len(features)
    for model in models:
        model.to(device).eval()
    for group in _batches([len(f) for f in features], batch):
        n = max(len(features[i]) for i in group)
        f = np.zeros((len(group), n, features[group[0]].shape[1]), np.float32)
        for j, i in enumerate(group):
            f[j, : len(features[i])] = features[i]
        ft = torch.from_numpy(f).to(device)
        probs = np.empty((len(models), len(group), n, models[0].config.n_classes), np.float32)
        for m, model in enumerate(models):
            state = None
            for c0 in range(0, n, chunk):
                logits, state = model(ft[:, c0 : c0 + chunk], state)  # (B, L, K)
                probs[m, :, c0 : c0 + chunk] = torch.softmax(logits, -1).cpu().numpy()
        for j, i in enumerate(group):
            out[i] = probs[:, j, : len(features[i])].copy()
    return out  # type: ignore[return-value]
