"""The frame predictor's outputs of one log, read per sample step: what the surprise track and the suggestions'
embeddings need, computed from per-frame arrays (often memory-mapped) only for the steps asked for.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .spectra import SpectralConfig, last_frame


class StepRows:
    """Per-frame rows ``(N, D)`` seen per sample step ``(T, D)``: each step holds the row of the last frame complete
    at or before it (zeros before the first), so the track is causal as the frames are.

    Supports ``len``, ``shape`` and ``[start:stop]`` along the first axis, as suggestions slice embeddings; an hour
    at 100 Hz is 360,000 steps of only 18,000 frames, so the steps are never materialised whole.
    """

    def __init__(self, rows: np.ndarray, n_samples: int, config: SpectralConfig) -> None:
        self.rows, self.config = rows, config
        self.shape = (n_samples, rows.shape[1])

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("StepRows supports [start:stop] slices only")
        start, stop, _ = key.indices(self.shape[0])
        stop = max(start, stop)
        which = last_frame(np.arange(start, stop), self.config)  # (L,)
        out = np.zeros((stop - start, self.shape[1]), np.float32)
        known = (which >= 0) & (which < len(self.rows))
        if known.any():
            lo, hi = int(which[known][0]), int(which[known][-1]) + 1
            block = np.asarray(self.rows[lo:hi], np.float32)  # only the frames these steps use are read
            out[known] = block[which[known] - lo]
        return out

    def segment_means(self, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
        """``(N, D)`` the mean over each span of steps ``[start, stop)``: ``self[start:stop].mean(axis=0)`` for every
        span at once, from prefix sums over the frames (a fleet's suggestion queue asks for half a million spans;
        expanding their steps took 44 s at 100 hours of logs)."""
        starts, stops = np.asarray(starts, np.int64), np.asarray(stops, np.int64)
        rows = np.asarray(self.rows, np.float64)  # (F, D)
        cum = np.concatenate([np.zeros((1, rows.shape[1])), np.cumsum(rows, axis=0)])  # (F + 1, D)
        first, hop, n = self.config.frame - 1, self.config.hop, len(rows)

        def prefix(t: np.ndarray) -> np.ndarray:  # (L,) -> (L, D): the sum over steps [0, t)
            done = np.maximum(np.minimum(t, self.shape[0]) - first, 0)  # steps from the first frame's
            whole, part = done // hop, done % hop  # frames every step of which is before t; steps of the next
            out = hop * cum[np.minimum(whole, n)]
            inside = whole < n  # steps past the last frame hold zeros
            out[inside] += part[inside, None] * rows[whole[inside]]
            return out

        return (prefix(stops) - prefix(starts)) / np.maximum(stops - starts, 1)[:, None]


@dataclass(frozen=True)
class FrameOutputs:
    """The frame predictor's outputs of one log.

    Attributes:
        frame_surprise: ``(N,)`` each frame's surprise (``frame_surprise``; the first frame 0).
        frame_hidden: ``(N, H)`` the hidden features after each frame (float16 in a session's cache).
        n_samples: Samples of the log.
        config: The front end the frames came from.
    """

    frame_surprise: np.ndarray
    frame_hidden: np.ndarray
    n_samples: int
    config: SpectralConfig

    def __len__(self) -> int:
        return self.n_samples

    def surprise(self) -> np.ndarray:
        """``(T,)`` float32 per sample step: the surprise of the last frame complete at or before it."""
        return StepRows(np.asarray(self.frame_surprise, np.float32)[:, None], self.n_samples, self.config)[:][:, 0]

    def step_frames(self) -> np.ndarray:
        """``(T,)`` the frame each sample step reads: the last complete at or before it (the first frame before it)."""
        return np.clip(last_frame(np.arange(self.n_samples), self.config), 0, max(len(self.frame_hidden) - 1, 0))

    def embedding(self) -> StepRows:
        """``(T, H)`` per sample step, computed for the rows sliced: the hidden features of the last frame."""
        return StepRows(self.frame_hidden, self.n_samples, self.config)
