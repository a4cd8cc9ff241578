"""Rows collected while reading a log, kept on disk past a small buffer, so a long log never sits in memory.

A reader appends one row of numbers per message. Python lists of floats cost ~35 bytes a number (690 MB for an hour
of 22 channels at 100 Hz); here a block of rows is filled in place and each full block is written to an anonymous
temporary file, which the operating system deletes when it is closed. The stamps stay in memory (8 bytes a message:
alignment searches them); the values come back as ``FileRows``, read a block at a time.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence

import numpy as np

from ..rowfiles import FileRows

BLOCK_ROWS = 8192
COPY_ROWS = 1 << 16  # rows per copy when reordering rows on disk


class RowBuffer:
    """Append-only stamps ``(N,)`` and ``(N, K)`` float64 values, the values spilled to a temporary file."""

    def __init__(self, width: int) -> None:
        self.width = width
        self._times = np.empty(BLOCK_ROWS, np.float64)
        self._block = np.empty((BLOCK_ROWS, width), np.float64)
        self._used = 0
        self._n = 0
        self._file = None

    def __len__(self) -> int:
        return self._n

    def append(self, time: float, row: Sequence[float]) -> None:
        if self._n == len(self._times):
            self._times = np.concatenate([self._times, np.empty_like(self._times)])
        self._times[self._n] = time
        self._block[self._used] = row
        self._used += 1
        self._n += 1
        if self._used == BLOCK_ROWS:
            self._flush()

    def append_block(self, times: np.ndarray, values: np.ndarray) -> None:
        """Append ``(n,)`` stamps and ``(n, K)`` values at once."""
        i = 0
        while i < len(times):
            take = min(len(times) - i, BLOCK_ROWS - self._used)
            while self._n + take > len(self._times):
                self._times = np.concatenate([self._times, np.empty_like(self._times)])
            self._times[self._n : self._n + take] = times[i : i + take]
            self._block[self._used : self._used + take] = values[i : i + take]
            self._used += take
            self._n += take
            i += take
            if self._used == BLOCK_ROWS:
                self._flush()

    def extend(self, rows: np.ndarray) -> None:
        """Append ``(n, K)`` values at once (no stamps: for copies of values only)."""
        self._flush()
        self._file.write(np.ascontiguousarray(rows, np.float64).tobytes())
        self._n += len(rows)

    def _flush(self) -> None:
        if self._file is None:
            self._file = tempfile.TemporaryFile(prefix="workbench-ingest-")  # noqa: SIM115 (lives with the rows)
        if self._used:
            self._file.write(self._block[: self._used].tobytes())
        self._used = 0

    def times(self) -> np.ndarray:
        """``(N,)`` stamps."""
        return self._times[: self._n].copy()

    def values(self) -> FileRows:
        """``(N, K)`` values, read from the spill file a block at a time."""
        self._flush()
        self._file.flush()
        return FileRows(self._file, 0, (self._n, self.width), np.dtype(np.float64))


def reorder(values: FileRows, order: np.ndarray) -> FileRows:
    """``values[order]`` as a new spilled ``FileRows``, copied a block at a time (reads gather within a block's
    span of rows, which stays short for logs that are only slightly out of order)."""
    out = RowBuffer(values.shape[1])
    for a in range(0, len(order), COPY_ROWS):
        idx = order[a : a + COPY_ROWS]
        lo, hi = int(idx.min()), int(idx.max()) + 1
        out.extend(values[lo:hi][idx - lo])
    return out.values()
