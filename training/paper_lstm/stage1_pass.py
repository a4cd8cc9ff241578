"""The paper family's stage 1 over whole logs: the LSTM predictor's hidden states, errors and estimates (what the
session's feature cache holds), and stage-2 features computed from them for the rows asked for.

Logs of different lengths are batched together and run in chunks of time with the LSTM state carried, so the
result equals one pass over each whole log while memory holds one chunk of each log in the batch, not the logs:
the outputs are written chunk by chunk into arrays the caller gives, which may be memory-mapped files.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from ..normalizer import Normalizer, Rows
from ..passes import chunk_for, padded_groups
from .lstm_config import FeatureMode
from .lstm_models import Predictor, feature_width, stage1_features


@dataclass(frozen=True)
class Stage1Outputs:
    """Per timestep of one log, all causal at ``t``. The arrays may be memory-mapped (the feature cache)."""

    hidden: np.ndarray  # (T, H) float32 or float16: state after x_t
    error: np.ndarray  # (T, C) float32: x_t − x̂_t in normalised units (0 at t = 0)
    estimate: np.ndarray  # (T, C) float32: x̂_{t+1}, normalised

    def __len__(self) -> int:
        return len(self.error)

    def features(self, mode: FeatureMode, start: int = 0, stop: int | None = None) -> np.ndarray:
        """``(stop − start, F)`` float32 features for stage 2 in ``mode``, of steps ``[start, stop)``."""
        part = slice(start, stop)

        def tensor(a: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.asarray(a[part], np.float32))

        return stage1_features(mode, tensor(self.hidden), tensor(self.estimate), tensor(self.error)).numpy()

    def lazy(self, mode: FeatureMode) -> LazyFeatures:
        """The ``mode`` features as an array-like that computes only the rows sliced from it."""
        return LazyFeatures(self, mode)

    def surprise(self, *, chunk: int = 1 << 16) -> np.ndarray:
        """``(T,)`` float32 mean squared error over channels, read a chunk at a time."""
        out = np.empty(len(self), np.float32)
        for a in range(0, len(self), chunk):
            out[a : a + chunk] = np.square(np.asarray(self.error[a : a + chunk], np.float32)).mean(axis=1)
        return out


class LazyFeatures:
    """Stage-2 features of one log, computed from its stage-1 outputs only for the rows asked for.

    The features of a 10-hour log are 3 GB; the cache they come from is memory-mapped, so slicing this reads and
    computes just the slice. Supports ``len``, ``shape`` and ``[start:stop]`` (step 1) along the first axis.
    """

    def __init__(self, outputs: Stage1Outputs, mode: FeatureMode) -> None:
        self.outputs, self.mode = outputs, mode
        # from the shapes, not a computed row: a session of thousands of logs would read every cache file for it
        self.shape = (len(outputs), feature_width(mode, outputs.hidden.shape[1], outputs.error.shape[1]))

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("LazyFeatures supports [start:stop] slices only")
        start, stop, _ = key.indices(self.shape[0])
        return self.outputs.features(self.mode, start, max(start, stop))


@torch.inference_mode()
def predictor_pass(
    predictor: Predictor,
    normalizer: Normalizer,
    arrays: Sequence[Rows],
    sinks: Sequence[Stage1Outputs],
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> None:
    """Stage 1 over whole raw logs, written chunk by chunk into ``sinks`` (writable ``(T, ·)`` arrays per log).

    Args:
        predictor: Stage 1.
        normalizer: Its input normalisation.
        arrays: Per log, the raw ``(T, C)`` samples (memory-mapped is fine: one chunk is read at a time).
        sinks: Per log, where its hidden states, errors and estimates go; each as long as its log.
        chunk: Steps per LSTM call (fewer when the batch is wide, see ``STEPS_PER_CALL``).
        batch: Logs per call.
        device: Torch device.
    """
    predictor = predictor.to(device).eval()
    for group in padded_groups([len(a) for a in arrays], batch):
        lengths = [len(arrays[i]) for i in group]
        n, c = max(lengths), arrays[group[0]].shape[1]
        step = chunk_for(len(group), chunk)
        state, last = None, np.zeros((len(group), c), np.float32)  # last: estimate made at the previous step
        for c0 in range(0, n, step):
            size = min(step, n - c0)
            x = np.zeros((len(group), size, c), np.float32)  # (B, L, C)
            for j, i in enumerate(group):
                if c0 < lengths[j]:
                    x[j, : min(size, lengths[j] - c0)] = normalizer(arrays[i][c0 : c0 + size])
            e, h, state = predictor(torch.from_numpy(x).to(device), state)  # (B, L, C), (B, L, H)
            est, hid = e.cpu().numpy(), h.cpu().numpy()
            err = np.empty_like(x)
            err[:, 0] = x[:, 0] - last if c0 else 0.0  # the first step of a log has no estimate
            err[:, 1:] = x[:, 1:] - est[:, :-1]
            last = est[:, -1]
            for j, i in enumerate(group):
                k = min(size, lengths[j] - c0)
                if k > 0:
                    sinks[i].hidden[c0 : c0 + k] = hid[j, :k]
                    sinks[i].estimate[c0 : c0 + k] = est[j, :k]
                    sinks[i].error[c0 : c0 + k] = err[j, :k]


def run_predictor(
    predictor: Predictor,
    normalizer: Normalizer,
    arrays: Sequence[Rows],
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> list[Stage1Outputs]:
    """Stage 1 over whole raw logs, in memory (``predictor_pass`` writes anywhere)."""
    h, c = predictor.config.hidden, predictor.config.n_channels
    outs = [
        Stage1Outputs(
            np.empty((len(a), h), np.float32), np.empty((len(a), c), np.float32), np.empty((len(a), c), np.float32)
        )
        for a in arrays
    ]
    predictor_pass(predictor, normalizer, arrays, outs, chunk=chunk, batch=batch, device=device)
    return outs
