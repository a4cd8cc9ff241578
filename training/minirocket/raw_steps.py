"""A log's per-step inputs for MiniRocket: each step holds the last ``length`` normalised samples as of the last
hop (zeros before the log's start), computed for the rows sliced only.

The classifier runs once per hop, not once per sample (a window moved by one sample of 170 barely changes its
features, and the transform is the costly part): steps between hops repeat the last hop's window, and the passes
run the network once per distinct row (``RocketClassifier.forward``), as the default family's frames do.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def hop_of(steps: np.ndarray, hop: int) -> np.ndarray:
    """The last hop at or before each step: steps ``hop - 1, 2·hop - 1, ...`` (``-1`` before the first)."""
    return (np.asarray(steps, np.int64) + 1) // hop * hop - 1


class RawSteps:
    """Supports ``len``, ``shape`` and ``[start:stop]`` along the first axis, as the passes read features.

    Args:
        rows: The log's raw samples ``(T, C)`` (an array or memory map: only the rows a slice needs are read).
        length: Samples per window.
        hop: Samples between windows.
        transform: The input normalisation (``training.Normalizer``), applied to the rows read.
    """

    def __init__(
        self, rows: np.ndarray, *, length: int, hop: int, transform: Callable[[np.ndarray], np.ndarray]
    ) -> None:
        self.rows, self.length, self.hop, self.transform = rows, length, hop, transform
        self.channels = int(rows.shape[1])
        self.shape = (len(rows), length * self.channels)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("RawSteps supports [start:stop] slices only")
        start, stop, _ = key.indices(self.shape[0])
        return self.at(np.arange(start, max(start, stop)))

    def at(self, steps: np.ndarray) -> np.ndarray:
        """The inputs of ``steps`` (ascending): ``(len(steps), L·C)``, each its last hop's window, oldest first."""
        ends = hop_of(steps, self.hop)  # (N,)
        out = np.zeros((len(ends), self.length, self.channels), np.float32)
        known = ends >= 0
        if known.any():
            lo = max(int(ends[known][0]) - self.length + 1, 0)
            block = np.asarray(self.transform(np.asarray(self.rows[lo : int(ends[-1]) + 1], np.float32)), np.float32)
            distinct, inverse = np.unique(ends[known], return_inverse=True)
            windows = np.zeros((len(distinct), self.length, self.channels), np.float32)
            for j, end in enumerate(distinct.tolist()):
                first = end - self.length + 1
                windows[j, max(0, -first) :] = block[max(first, 0) - lo : end + 1 - lo]
            out[known] = windows[inverse]
        return out.reshape(len(ends), -1)

    def hop_rows(self, start: int, stop: int) -> np.ndarray:
        """The steps of ``[start, stop)`` at which a window completes: one row per distinct input."""
        first = start + (self.hop - 1 - start) % self.hop
        return np.arange(first, stop, self.hop, dtype=np.int64)
