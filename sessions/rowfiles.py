"""Row-wise reading and writing of ``(N, K)`` arrays on disk, a block of rows at a time, without memory maps.

A memory-mapped file counts every page touched in the process's resident memory until the kernel needs it back:
scoring a 10-hour log through maps showed gigabytes resident. Here rows move with ``pread`` and ``write`` through the
page cache, which the kernel owns, so what a long log costs this process is the block in hand.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Sequence
from pathlib import Path
from typing import BinaryIO

import numpy as np


class FileRows:
    """Read-only ``(N, K)`` rows of a file, sliced like an array along its first axis.

    ``rows[a:b]`` reads those rows with one ``pread``; ``rows[a:b, c]`` picks columns after reading. ``select`` gives
    a view on some columns. ``len``, ``shape`` and ``dtype`` as for an array.
    """

    def __init__(
        self,
        source: Path | BinaryIO,
        offset: int,
        shape: tuple[int, int],
        dtype: np.dtype,
        cols: Sequence[int] | None = None,
    ) -> None:
        # A path is opened for each read (a session may hold thousands of logs: no descriptor stays open); an open
        # file (an anonymous temporary one has no path) is read through its descriptor.
        self._source, self._offset = source, offset
        self._rows, self._width = shape
        self.dtype = np.dtype(dtype)
        self._cols = None if cols is None else np.asarray(cols, np.int64)
        self.shape = (self._rows, self._width if cols is None else len(cols))

    @classmethod
    def open_npy(cls, path: str | Path) -> FileRows:
        """The rows of a 2-D, C-ordered ``.npy`` file."""
        path = Path(path)
        with open(path, "rb") as f:
            version = np.lib.format.read_magic(f)
            shape, fortran, dtype = (
                np.lib.format.read_array_header_1_0(f) if version == (1, 0) else np.lib.format.read_array_header_2_0(f)
            )
            if fortran or len(shape) != 2:
                raise ValueError(f"{path}: expected a C-ordered 2-D array, found shape {shape}")
            return cls(path, f.tell(), shape, dtype)

    def _read_into(self, out: np.ndarray, offset: int) -> None:
        view = memoryview(out).cast("B")
        with contextlib.ExitStack() as stack:
            if isinstance(self._source, Path):
                fd = stack.enter_context(open(self._source, "rb")).fileno()
            else:
                fd = self._source.fileno()
            done = 0
            while done < len(view):  # a read may return less than asked (past 2 GB, or a signal)
                got = os.preadv(fd, [view[done:]], offset + done)
                if got == 0:
                    raise OSError(f"{self._source}: short read (the file was truncated)")
                done += got

    def __len__(self) -> int:
        return self._rows

    def select(self, cols: Sequence[int]) -> FileRows:
        """The same rows, only ``cols`` (indices into the current columns)."""
        base = np.arange(self._width) if self._cols is None else self._cols
        return FileRows(self._source, self._offset, (self._rows, self._width), self.dtype, base[list(cols)])

    def __getitem__(self, key: slice | tuple) -> np.ndarray:
        cols = None
        if isinstance(key, tuple):
            key, cols = key
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("rows support [start:stop] and [start:stop, cols] only")
        a, b, _ = key.indices(self._rows)
        b = max(a, b)
        row_bytes = self._width * self.dtype.itemsize
        out = np.empty((b - a, self._width), self.dtype)
        self._read_into(out, self._offset + a * row_bytes)
        if self._cols is not None:
            out = out[:, self._cols]
        return out if cols is None else out[:, cols]

    def column_any(self, *, block: int = 1 << 16) -> np.ndarray:
        """``(K,)`` whether each column holds any non-zero value."""
        out = np.zeros(self.shape[1], bool)
        for a in range(0, self._rows, block):
            out |= self[a : a + block].any(axis=0)
        return out


class NpyWriter:
    """Writes a ``.npy`` file of a known ``(N, K)`` shape row block by row block, in order.

    ``writer[a:b] = block`` appends rows ``a`` to ``b`` (``a`` must be where the last block ended), so passes that
    write their outputs by slicing can write straight to disk. ``close`` checks that every row came and syncs the
    file to disk; ``abort`` removes it.
    """

    def __init__(self, path: str | Path, shape: tuple[int, int], dtype: np.dtype | type) -> None:
        self.path = Path(path)
        self.shape = tuple(int(x) for x in shape)
        self.dtype = np.dtype(dtype)
        self._next = 0
        self._file = open(self.path, "wb")  # noqa: SIM115 (closed by close or abort)
        header = {"descr": np.lib.format.dtype_to_descr(self.dtype), "fortran_order": False, "shape": self.shape}
        np.lib.format.write_array_header_2_0(self._file, header)

    def __len__(self) -> int:
        return self.shape[0]

    def __setitem__(self, key: slice, value: np.ndarray) -> None:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("NpyWriter takes [start:stop] = rows only")
        a, b, _ = key.indices(self.shape[0])
        if a != self._next:
            raise ValueError(f"{self.path}: rows must be written in order (expected row {self._next}, got {a})")
        block = np.ascontiguousarray(value, self.dtype).reshape(b - a, *self.shape[1:])
        self._file.write(block.tobytes())
        self._next = b

    def close(self, *, sync: bool = True) -> None:
        """Finish the file: every row written and flushed; synced to disk unless ``sync`` is false (derived data
        that can be recomputed: thousands of small files would each wait for the disk)."""
        if self._next != self.shape[0]:
            self.abort()
            raise ValueError(f"{self.path}: {self._next} of {self.shape[0]} rows written")
        self._file.flush()
        if sync:
            os.fsync(self._file.fileno())
        self._file.close()

    def abort(self) -> None:
        """Close and remove the partial file."""
        self._file.close()
        self.path.unlink(missing_ok=True)
