"""Labelled rows held as the frames they read: what stage 2's fits draw their batches from.

A row is the last ``window`` frames at a step, stacked (``(W·F,)``: 12.6 KiB at 22 channels). Consecutive rows of a
segment share all but one frame, so a segment's stacked rows take ``window`` times the memory of its frames: at
100 hours with 5 % labelled, 1.2 GB per fit against 0.17 GB. :class:`WindowRows` keeps each segment's frames once and
where every row's window starts in them, and stacks the rows a batch asks for when it is drawn; the numbers are those
``SpectralSteps.at`` gives (a window short of frames at a log's start repeats its first frame).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .spectra import SpectralSteps, last_frame

Span = tuple[int, int, int]  # (log index, start, stop) in steps


def at_most(n: int, most: int, seed: Sequence[int]) -> np.ndarray:
    """Indices of ``n`` rows: all of them, or a seeded draw of ``most`` in ascending order (what the drift reads of a
    fleet's labelled rows)."""
    if n <= most:
        return np.arange(n)
    return np.sort(np.random.default_rng(list(seed)).choice(n, most, replace=False))


class WindowRows:
    """Rows ``(N, W·F)`` of stacked frame windows, held as their frames ``(M, F)`` and each row's first frame.

    Supports ``len``, ``shape``, ``take(idx)`` and ``[start:stop]``; ``dense()`` builds every row (for what needs
    them all at once, such as run-to-run augmentation's mixing).
    """

    def __init__(self, frames: np.ndarray, first: np.ndarray, window: int) -> None:
        self.frames = frames  # (M, F) float32
        self.first = first  # (N,) int64
        self.window = window
        self.shape = (len(first), window * frames.shape[1])
        self._offsets = np.arange(window, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.first)

    @property
    def nbytes(self) -> int:
        return self.frames.nbytes + self.first.nbytes

    def take(self, idx: np.ndarray) -> np.ndarray:
        """Rows ``idx`` stacked: ``(len(idx), W·F)`` float32."""
        first = self.first[np.asarray(idx, np.int64)]  # (n,)
        return self.frames[first[:, None] + self._offsets].reshape(len(first), self.shape[1])

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("WindowRows supports [start:stop] slices and take() only")
        start, stop, _ = key.indices(len(self))
        return self.take(np.arange(start, max(start, stop)))

    def dense(self) -> np.ndarray:
        """Every row stacked: ``(N, W·F)``."""
        return self.take(np.arange(len(self)))


def window_rows(features: Sequence[SpectralSteps], spans: Sequence[Span], steps_of) -> tuple[WindowRows, np.ndarray]:
    """The rows of ``spans``, span after span, and where each span's rows begin and end ``(S + 1,)``.

    Args:
        features: Per log, its per-step inputs (their frames are read once per span, a slice of the log's).
        spans: ``(log index, start, stop)``.
        steps_of: ``(features, start, stop) -> (n,)`` the ascending steps whose rows a span contributes (each at
            or after its log's first complete frame).
    """
    window = features[0].config.window if features else 1
    width = features[0].frames.shape[1] if features else 0
    # first where each span's frames go, then one array filled span by span, each log's mapped pages given back
    # once copied: read whole before copying, the labels' reads at 100 h held every log's frames (1.7 GiB) mapped
    plans, firsts, counts, offset = [], [], [], 0
    for i, a, b in spans:
        f = features[i]
        steps = np.asarray(steps_of(f, a, b), np.int64)
        counts.append(len(steps))
        if not len(steps):
            continue
        which = last_frame(steps, f.config)  # (n,) the frame each row's window ends at
        start = int(which[0]) - window + 1  # may be before the log's first frame: those repeat it
        stop = int(which[-1]) + 1
        plans.append((i, start, stop, offset))
        firsts.append(offset + which - int(which[0]))
        offset += stop - start
    frames = np.empty((offset, width), np.float32)
    for i, start, stop, at in plans:
        lo = max(start, 0)
        frames[at + lo - start : at + stop - start] = features[i].frames[lo:stop]
        frames[at : at + lo - start] = frames[at + lo - start]  # a window before the log's first frame repeats it
        features[i].release()
    first = np.concatenate(firsts) if firsts else np.zeros(0, np.int64)
    bounds = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])
    return WindowRows(frames, first, window), bounds
