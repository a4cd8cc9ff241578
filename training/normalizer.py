"""Per-channel normalisation of raw logs, shared by every family, and what a log is read as."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Rows(Protocol):
    """A ``(T, C)`` log read by rows: a NumPy array, a memory map, or a file read on demand."""

    shape: tuple[int, ...]

    def __len__(self) -> int: ...

    def __getitem__(self, key: slice) -> np.ndarray: ...


@dataclass(frozen=True)
class Normalizer:
    """Per-channel zero mean, unit variance (the paper normalises every input dimension)."""

    mean: np.ndarray  # (C,) float32
    std: np.ndarray  # (C,) float32

    @classmethod
    def fit(cls, arrays: Sequence[Rows], *, block: int = 1 << 16) -> Normalizer:
        """Mean and std over every sample of ``arrays`` (each ``(T, C)``), in one streaming pass.

        Read ``block`` rows at a time, so a memory-mapped or file-backed log is never held whole.
        """
        n = 0
        total = None
        total_sq = None
        for a in arrays:
            for b0 in range(0, len(a), block):
                a64 = np.asarray(a[b0 : b0 + block], dtype=np.float64)  # (≤block, C)
                s, sq = a64.sum(axis=0), np.square(a64).sum(axis=0)
                total = s if total is None else total + s
                total_sq = sq if total_sq is None else total_sq + sq
                n += a64.shape[0]
        if total is None or n == 0:
            raise ValueError("no samples to normalise")
        mean = total / n
        var = np.maximum(total_sq / n - mean**2, 0.0)
        std = np.sqrt(var)
        std[std < 1e-8] = 1.0  # a constant channel stays constant (zero) instead of blowing up
        return cls(mean.astype(np.float32), std.astype(np.float32))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return ((np.asarray(x, dtype=np.float32) - self.mean) / self.std).astype(np.float32)

    def to_dict(self) -> dict[str, list[float]]:
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, d: dict[str, list[float]]) -> Normalizer:
        return cls(np.asarray(d["mean"], np.float32), np.asarray(d["std"], np.float32))
