"""Change points in a log's signals, and snapping a rough range's edges to them.

Terrain transitions change the statistics of the signals and of the stage-1 prediction error. The signals are
summarised in short blocks (mean and spread of each column), scaled by a robust noise estimate, and segmented with
``ruptures``' kernel change-point detection (linear kernel, penalised: a C implementation, linear in the number of
blocks in practice), its compiled search loaded alone (:func:`_kernel_pelt`).
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import itertools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Snap:
    """A proposal for a rough range: where its edges move, and whether each moved."""

    start: int
    stop: int
    moved_start: bool
    moved_stop: bool

    @property
    def moved(self) -> bool:
        return self.moved_start or self.moved_stop


def block_summary(signal: np.ndarray, block: int) -> np.ndarray:
    """Mean and standard deviation of each column over consecutive blocks: ``(T, C)`` -> ``(T // block, 2C)``.

    A tail shorter than a block is dropped.
    """
    x = np.asarray(signal, np.float64)
    if x.ndim == 1:
        x = x[:, None]
    n = len(x) // block
    if n == 0:
        return np.zeros((0, 2 * x.shape[1]))
    b = x[: n * block].reshape(n, block, x.shape[1])  # (N, block, C)
    return np.concatenate([b.mean(axis=1), b.std(axis=1)], axis=1)


def _robust_scale(z: np.ndarray) -> np.ndarray:
    """Scale each column by its noise level, estimated from first differences (robust to the steps themselves)."""
    if len(z) < 3:
        return z
    d = np.diff(z, axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826 / np.sqrt(2.0)
    scale = np.where(mad > 1e-9, mad, np.maximum(z.std(axis=0), 1e-9))
    return (z - np.median(z, axis=0)) / scale


def change_points(signal: np.ndarray, *, block: int = 25, penalty: float = 3.0, min_blocks: int = 4) -> np.ndarray:
    """Sample indices where the signal's statistics change.

    Args:
        signal: ``(T, C)`` (or ``(T,)``) signals of one log, e.g. the channels and the prediction error.
        block: Samples per summary block (the resolution of the result).
        penalty: Cost of a change, per summary dimension and per log of the number of blocks; larger finds fewer.
        min_blocks: Shortest stretch between two changes, in blocks.

    Returns:
        ``(N,)`` sorted int64 indices in ``(0, T)``, multiples of ``block``.
    """
    z = block_summary(signal, block)
    if len(z) < 2 * min_blocks:
        return np.zeros(0, np.int64)
    z = _robust_scale(z)
    pen = penalty * z.shape[1] * np.log(len(z))
    # KernelCPD(kernel="linear", min_size=min_blocks).fit(z).predict(pen=pen): its search, and its walk back
    path = _kernel_pelt()(np.ascontiguousarray(z, np.float64), float(pen), int(min_blocks))  # (N + 1,) the last cut
    ends, end = [], len(z)
    while end > 0:
        ends.append(end)
        end = int(path[end])
    return np.asarray(ends[:0:-1], np.int64) * block  # the cuts before len(z), ascending


@functools.cache
def _kernel_pelt() -> Callable[[np.ndarray, float, int], np.ndarray]:
    """``ruptures``' compiled penalised search with the linear kernel (``ekcpd_pelt_L2``), loaded without running
    ``ruptures``' package ``__init__``, which imports every detector and cost and, through its rank cost, all of
    ``scipy.stats``: 1.3 s, a third of ``workbench classify`` of a ten-minute run. Where the compiled module is not
    where ruptures 1.1 keeps it, ``ruptures`` is imported as usual (the same function, the same cuts)."""
    spec = importlib.util.find_spec("ruptures")  # finds the package without running it
    folder = Path(next(iter(spec.submodule_search_locations or ()), "")) / "detection" / "_detection" if spec else None
    name = "ruptures.detection._detection.ekcpd"
    for suffix in importlib.machinery.EXTENSION_SUFFIXES if folder is not None else ():
        path = folder / f"ekcpd{suffix}"
        if path.is_file():
            loader = importlib.machinery.ExtensionFileLoader(name, str(path))
            module = importlib.util.module_from_spec(importlib.util.spec_from_loader(name, loader))
            loader.exec_module(module)
            return module.ekcpd_pelt_L2
    from ruptures.detection._detection.ekcpd import ekcpd_pelt_L2

    return ekcpd_pelt_L2


def snap_range(start: int, stop: int, points: np.ndarray, *, radius: int) -> Snap:
    """Move each edge of ``[start, stop)`` to the nearest change point within ``radius`` samples.

    An edge with no change point that near stays. The proposal is never empty: an edge that would cross the other
    stays where it was.
    """
    pts = np.asarray(points, np.int64)

    def nearest(edge: int) -> int | None:
        if len(pts) == 0:
            return None
        i = int(np.argmin(np.abs(pts - edge)))
        return int(pts[i]) if abs(int(pts[i]) - edge) <= radius else None

    a, b = nearest(start), nearest(stop)
    new_a = a if a is not None and a < stop else start
    new_b = b if b is not None and b > new_a else stop
    return Snap(new_a, new_b, new_a != start, new_b != stop)


def spans(length: int, points: np.ndarray, *, max_len: int, min_len: int = 1) -> list[tuple[int, int]]:
    """Cut ``[0, length)`` at the change points, then cut longer stretches into equal pieces of at most ``max_len``,
    or, where pieces that short would fall under ``min_len``, into as many as keep each at least ``min_len`` (under
    ``2 * min_len``): every stretch of ``min_len`` or more yields pieces.

    Stretches shorter than ``min_len`` are dropped.
    """
    return [(int(a), int(b)) for a, b in span_array(length, points, max_len=max_len, min_len=min_len)]


def span_array(length: int, points: np.ndarray, *, max_len: int, min_len: int = 1) -> np.ndarray:
    """:func:`spans` as an ``(N, 2)`` int64 array of ``(start, stop)``, computed without a loop over the stretches
    (a fleet's hours hold hundreds of thousands of them: the suggestion queue cuts every log each time it ranks)."""
    pts = np.asarray(points, np.int64).reshape(-1)
    edges = np.unique(np.concatenate([[0, length], pts[(pts > 0) & (pts < length)]]))
    a, b = edges[:-1], edges[1:]  # (S,) stretches between change points, none empty
    if not len(a):
        return np.zeros((0, 2), np.int64)
    # (S,) pieces of at most max_len, but never so many that they fall under min_len: with a pick no shorter than
    # one classifier window (max_len = min_len), a stretch of 2.5 windows cut in three pieces would yield none
    pieces = np.maximum(1, np.minimum(-(-(b - a) // max_len), (b - a) // max(1, min_len)))
    which = np.repeat(np.arange(len(a)), pieces)  # (P,) the stretch of each piece
    k = np.arange(len(which)) - np.repeat(np.cumsum(pieces) - pieces, pieces)  # (P,) its place in the stretch
    step = (b - a) / pieces

    def cut(j: np.ndarray) -> np.ndarray:  # as np.linspace(a, b, pieces + 1) places it: j * step + a, b exactly last
        return np.where(j == pieces[which], b[which], np.round(j * step[which] + a[which])).astype(np.int64)

    out = np.stack([cut(k), cut(k + 1)], axis=1)  # (P, 2)
    return out[out[:, 1] - out[:, 0] >= min_len]


def stretch_agreement(labels: np.ndarray, points: np.ndarray) -> float | None:
    """The share of steps whose label ``(T,)`` (non-negative ints) is the most frequent one of their stretch, the
    stretches cut at the change points ``points``; ``None`` for no steps.

    Where each stretch between change points is one terrain, a classifier's accuracy on it is at most this, and
    equal to it when each stretch's most predicted terrain is the right one: an expected accuracy that needs no
    label (measured: within 10 points of what held-out BorealTC runs scored on 91 % of them with each run one
    stretch, 72 % with each cut at its change points, 79 % with none of the stretches under 10 s:
    :func:`coarser_points`).
    """
    labels = np.asarray(labels, np.int64)
    n = len(labels)
    if n == 0:
        return None
    edges = [0, *sorted(int(p) for p in points if 0 < p < n), n]
    agree = sum(int(np.bincount(labels[a:b]).max()) for a, b in itertools.pairwise(edges) if b > a)
    return agree / n


def coarser_points(points: np.ndarray, n: int, min_length: int) -> np.ndarray:
    """The change points ``points`` of ``n`` steps with no stretch under ``min_length`` steps: from the start, a
    point is kept where the stretch it closes and the steps after it both hold ``min_length`` or more, so a short
    stretch joins the one before it (the first joins the next)."""
    kept: list[int] = []
    last = 0
    for p in sorted(int(p) for p in points if 0 < p < n):
        if p - last >= min_length and n - p >= min_length:
            kept.append(p)
            last = p
    return np.asarray(kept, np.int64)
