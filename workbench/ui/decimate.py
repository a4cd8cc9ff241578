"""Min/max-per-pixel decimation of a window of a log, so the browser gets ~2 points per pixel, never the whole log.

Written with NumPy rather than ``tsdownsample``: that library returns one index set per channel, while uPlot draws
every series of a chart against one shared x array, and a single ``reduceat`` over all channels at once is as fast
here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Decimated:
    """A window ready to draw.

    Attributes:
        t: ``(P,)`` seconds since the log's start, ascending.
        values: ``(P, C)`` the channels at ``t`` (float32).
        step: Samples per bucket (1: every sample is sent).
    """

    t: np.ndarray
    values: np.ndarray
    step: int


def decimate(samples: np.ndarray, start: int, *, rate_hz: float, pixels: int) -> Decimated:
    """Min and max of every pixel-wide bucket of ``samples``, in time order within each bucket.

    Args:
        samples: ``(N, C)`` the visible window of a log (a view into the memory-mapped array is fine).
        start: Index of ``samples[0]`` in the log, for the time axis.
        rate_hz: Sample rate of the log.
        pixels: Width of the chart in pixels; at most ``2 · pixels`` points come back.

    Returns:
        Every sample when the window has at most ``2 · pixels`` of them, else two points per bucket: the first
        sample's time carries the earlier extreme and the bucket's midpoint the later one, so spikes survive.
    """
    n = len(samples)
    if n <= 2 * pixels:
        return Decimated((start + np.arange(n)) / rate_hz, np.asarray(samples, np.float32), 1)
    step = -(-n // pixels)  # ceil: buckets of equal width
    edges = np.arange(0, n, step)  # (B,)
    x = np.asarray(samples, np.float32)
    lo = np.minimum.reduceat(x, edges, axis=0)  # (B, C)
    hi = np.maximum.reduceat(x, edges, axis=0)  # (B, C)
    # which extreme comes first within the bucket keeps the drawn path faithful to the signal's direction
    arg_lo = _arg_reduceat(x, edges, lo)
    arg_hi = _arg_reduceat(x, edges, hi)
    first = np.where(arg_lo <= arg_hi, lo, hi)
    second = np.where(arg_lo <= arg_hi, hi, lo)
    b = len(edges)
    values = np.empty((2 * b, x.shape[1]), np.float32)
    values[0::2], values[1::2] = first, second
    widths = np.diff(np.append(edges, n))
    t = np.empty(2 * b)
    t[0::2] = start + edges
    t[1::2] = start + edges + widths / 2
    return Decimated(t / rate_hz, values, step)


def _arg_reduceat(x: np.ndarray, edges: np.ndarray, extreme: np.ndarray) -> np.ndarray:
    """``(B, C)`` offset within each bucket of the first sample equal to the bucket's ``extreme``."""
    bucket = np.repeat(np.arange(len(edges)), np.diff(np.append(edges, len(x))))  # (N,)
    hit = x == extreme[bucket]  # (N, C)
    pos = np.where(hit, np.arange(len(x))[:, None], len(x))  # (N, C)
    return np.minimum.reduceat(pos, edges, axis=0)


def decimate_track(track: np.ndarray, start: int, stop: int, t: np.ndarray, *, rate_hz: float) -> np.ndarray:
    """A per-sample track (``(T,)``, any dtype) at the decimated times ``t`` (nearest sample at or before)."""
    idx = np.clip(np.round(t * rate_hz).astype(np.int64), start, max(start, stop - 1))
    return track[idx]
