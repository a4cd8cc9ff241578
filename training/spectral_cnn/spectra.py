"""The spectral front end: what terrain is made of, as features a classifier can use with few labels.

Terrain shows in how a robot vibrates: the short-time spectrum of its fast channels (IMU at 100 Hz and more), and in
the level of its slow ones (wheel speeds and motor currents at a few Hz, held between their samples after
alignment). BorealTC's CNN reads exactly this (log spectrograms of 0.4 s frames); a logistic regression on their
mean and spread over 1.7 s reached 88 % with a tenth of the labels where the paper's LSTM features reach 74 %.

Everything is causal: the frame that ends at step ``t`` uses samples ``t - frame + 1 .. t`` only, and a step's
features are those of the last frame complete at or before it, so the streaming runtime computes the same numbers
as the offline pass (:class:`SpectralStream`). Arrays in, arrays out; no torch.
"""

from __future__ import annotations

import functools
import mmap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

CHUNK_FRAMES = 4096  # frames computed at a time: a 10-hour log never builds its (N, C, frame) view whole


@dataclass(frozen=True)
class SpectralConfig:
    """Sizes of the front end, in samples of the aligned log.

    Attributes:
        frame: Samples per short-time frame (0.4 s at 100 Hz, as BorealTC's CNN).
        hop: Samples between frame ends: the frame rate is ``rate / hop`` (5 Hz at 100 Hz).
        fast: Channels given log power spectra (``frame // 2 + 1`` bins each).
        slow: Channels given mean, spread, minimum and maximum over the frame.
        eps: Floor of the power before the log (normalised units squared).
        detrend: Remove each frame's mean before its spectrum (the vibration only); False keeps the level in the
            lowest bin (gravity's direction, a steady turn).
        window: Frames a step's summary spans (mean and spread of the last ``window`` frames): 7 frames of 0.4 s
            every 0.2 s cover 1.6 s, BorealTC's 1.7 s window.
    """

    frame: int = 40
    hop: int = 20
    fast: tuple[int, ...] = ()
    slow: tuple[int, ...] = ()
    eps: float = 1e-6
    detrend: bool = True
    window: int = 7

    @property
    def bins(self) -> int:
        """Spectral bins per fast channel."""
        return self.frame // 2 + 1

    @property
    def width(self) -> int:
        """Features per frame: ``bins`` per fast channel, 4 statistics per slow channel."""
        return self.bins * len(self.fast) + 4 * len(self.slow)

    @property
    def summary_width(self) -> int:
        """Features per step: the mean and spread of each frame feature over the window."""
        return 2 * self.width

    @property
    def step_width(self) -> int:
        """Inputs per step of the default classifier: the last ``window`` frames, oldest first."""
        return self.window * self.width

    @property
    def span(self) -> int:
        """Samples one summary covers."""
        return self.frame + (self.window - 1) * self.hop

    @classmethod
    def for_log(cls, x: np.ndarray, rate_hz: float, *, detrend: bool = False) -> SpectralConfig:
        """Sizes for a log at ``rate_hz`` (0.4 s frames every 0.2 s, 1.6 s windows) and its fast and slow channels.

        ``detrend`` is off by default: on BorealTC's inner folds the level kept in the lowest bin was chosen on most
        folds (``benchmarks/studies/spectral_baseline.py``).
        """
        fast, slow = split_channels(x)
        frame = max(4, round(0.4 * rate_hz))
        return cls(frame=frame, hop=max(1, round(0.2 * rate_hz)), fast=fast, slow=slow, detrend=detrend)

    def to_dict(self) -> dict:
        """JSON-able (the bundle's ``model.json``)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.__dict__.items()}

    @classmethod
    def from_dict(cls, d: dict) -> SpectralConfig:
        """Inverse of :meth:`to_dict`."""
        return cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def split_channels(x: np.ndarray, *, held: float = 0.5) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Fast and slow channels of an aligned log ``(T, C)``: a channel whose value changes on fewer than ``held`` of
    its steps was sampled slower than the log's rate and held between samples (alignment holds values)."""
    x = np.asarray(x)
    if len(x) < 2:
        return tuple(range(x.shape[1])), ()
    changes = (np.diff(x, axis=0) != 0).mean(axis=0)  # (C,)
    fast = tuple(int(i) for i in np.flatnonzero(changes >= held))
    slow = tuple(int(i) for i in np.flatnonzero(changes < held))
    return fast, slow


def frame_ends(n_samples: int, config: SpectralConfig) -> np.ndarray:
    """``(N,)`` the step at which each frame is complete: ``frame - 1``, then every ``hop`` steps."""
    if n_samples < config.frame:
        return np.zeros(0, np.int64)
    return np.arange(config.frame - 1, n_samples, config.hop, dtype=np.int64)


def frame_features(x: np.ndarray, config: SpectralConfig) -> np.ndarray:
    """Features of every complete frame of a log.

    Args:
        x: ``(T, C)`` aligned samples (normalised or raw; the log makes the spectra scale-free up to an offset).
        config: Sizes and channels.

    Returns:
        ``(N, F)`` float32, one row per frame ending at :func:`frame_ends`; ``F = config.width``.
    """
    x = np.asarray(x, np.float32)
    ends = frame_ends(len(x), config)
    out = np.empty((len(ends), config.width), np.float32)
    for a in range(0, len(ends), CHUNK_FRAMES):
        e = ends[a : a + CHUNK_FRAMES]
        idx = e[:, None] - config.frame + 1 + np.arange(config.frame)[None, :]  # (n, L) sample indices
        segment_features(x[idx], config, out=out[a : a + len(e)])
    return out


def drop_pages(array: np.ndarray) -> None:
    """Give back the pages a pass over a memory-mapped ``array`` (a cached log's frames) put in this process's
    resident set; the file's pages stay in the kernel's cache, and a later read maps them again. Without it a pass
    over every log holds the whole cache resident: 3.3 GB of frames at 100 hours of 22 channels. Nothing for an
    array in memory."""
    base = array
    while isinstance(base, np.ndarray):
        base = base.base
    if isinstance(base, mmap.mmap) and hasattr(mmap, "MADV_DONTNEED"):
        base.madvise(mmap.MADV_DONTNEED)


def frame_moments(logs: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and spread ``(F,)`` of the frames ``(N, F)`` of every log, summed a log at a time: a fleet's
    frames never sit in memory together, nor stay resident once read (:func:`drop_pages`)."""
    n, total, total_sq = 0, 0.0, 0.0
    for frames in logs:
        rows = np.asarray(frames, np.float64)  # (N, F) of one log
        n += len(rows)
        total = total + rows.sum(0)
        total_sq = total_sq + np.square(rows).sum(0)
        del rows
        drop_pages(frames)
    mean = total / max(n, 1)
    std = np.sqrt(np.maximum(total_sq / max(n, 1) - np.square(mean), 0.0))
    return np.asarray(mean, np.float32), np.asarray(std, np.float32)


@functools.lru_cache(maxsize=8)
def _spectrum_matrix(frame: int) -> np.ndarray:
    """``(L, 2·bins)`` float32: a frame's samples -> real and imaginary parts of its Hamming-windowed spectrum. One
    product instead of a window product and an FFT: on one frame (the streaming step) each NumPy call's overhead
    costs more than its arithmetic."""
    spectrum = np.fft.rfft(np.diag(np.hamming(frame)), axis=1)  # (L, bins) row j: the spectrum of sample j alone
    return np.concatenate([spectrum.real, spectrum.imag], axis=1).astype(np.float32)


def segment_features(segments: np.ndarray, config: SpectralConfig, *, out: np.ndarray | None = None) -> np.ndarray:
    """Features of frames already cut: ``(n, L, C)`` samples -> ``(n, F)`` (written into ``out`` when given).

    The offline pass and the streaming step share this function, so they compute the same numbers. Means are sums
    divided (``np.mean`` and ``np.std`` cost several calls each, and the streaming step runs this on one frame).
    """
    n, length = len(segments), np.float32(segments.shape[1])
    out = np.empty((n, config.width), np.float32) if out is None else out
    n_fast = config.bins * len(config.fast)
    fast, slow = _channel_index(config)
    if len(fast):
        seg = segments[:, :, fast].transpose(0, 2, 1)  # (n, Cf, L)
        if config.detrend:  # before the product: folded into it, the level's rounding would swamp small spectra
            seg = seg - seg.sum(axis=2, keepdims=True) / length  # the spectrum of the vibration, not of the level
        parts = seg @ _spectrum_matrix(config.frame)  # (n, Cf, 2·bins)
        parts *= parts
        power = parts[:, :, : config.bins] + parts[:, :, config.bins :]  # (n, Cf, bins) re² + im²
        power += np.float32(config.eps)
        out[:, :n_fast] = np.log(power, out=power).reshape(n, -1)
    if len(slow):
        seg = segments[:, :, slow]  # (n, L, Cs)
        stats = np.empty((n, len(slow), 4), np.float32)
        mean = np.divide(seg.sum(axis=1), length, out=stats[:, :, 0])  # (n, Cs)
        dev = seg - mean[:, None, :]
        dev *= dev
        np.sqrt(dev.sum(axis=1) / length, out=stats[:, :, 1])
        np.min(seg, axis=1, out=stats[:, :, 2])
        np.max(seg, axis=1, out=stats[:, :, 3])
        out[:, n_fast:] = stats.reshape(n, -1)
    return out


@functools.lru_cache(maxsize=8)
def _channel_index(config: SpectralConfig) -> tuple[np.ndarray, np.ndarray]:
    """The fast and the slow channels' indices as arrays (a tuple would be turned into one at every call)."""
    return np.asarray(config.fast, np.int64), np.asarray(config.slow, np.int64)


def per_step(frames: np.ndarray, n_samples: int, config: SpectralConfig) -> tuple[np.ndarray, np.ndarray]:
    """Each step's features: the last frame complete at or before it (zeros before the first).

    Returns:
        ``(T, F)`` features and ``(T,)`` bool, True where a frame is known.
    """
    ends = frame_ends(n_samples, config)
    which = np.searchsorted(ends, np.arange(n_samples), side="right") - 1  # (T,) -1 before the first frame
    known = which >= 0
    out = np.zeros((n_samples, frames.shape[1] if frames.ndim == 2 else config.width), np.float32)
    out[known] = frames[which[known]]
    return out, known


class SpectralStream:
    """The front end one sample at a time, for ``B`` streams: the same frames as :func:`frame_features`.

    Keeps the last ``frame`` samples of each stream in a ring; a step that completes a frame computes it, any other
    step returns the last frame's features.
    """

    def __init__(self, config: SpectralConfig, n_channels: int, *, streams: int = 1) -> None:
        self.config = config
        self.order = np.arange(config.frame)  # (L,) ring positions from the oldest sample, shifted per stream
        self.ring = np.zeros((streams, config.frame, n_channels), np.float32)  # (B, L, C)
        self.count = np.zeros(streams, np.int64)  # samples seen per stream
        self.last = np.zeros((streams, config.width), np.float32)  # (B, F)
        self.known = np.zeros(streams, bool)
        self.completed = np.zeros(streams, bool)  # which streams completed a frame at the last step

    def reset(self, stream: int | None = None) -> None:
        """Forget one stream (or all): its next sample starts a log."""
        sel = slice(None) if stream is None else stream
        self.ring[sel] = 0.0
        self.count[sel] = 0
        self.last[sel] = 0.0
        self.known[sel] = False

    def step(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Take one sample per stream ``(B, C)``; return ``(B, F)`` features and ``(B,)`` known."""
        cfg = self.config
        pos = self.count % cfg.frame
        self.ring[np.arange(len(x)), pos] = x
        self.count += 1
        done = (self.count >= cfg.frame) & ((self.count - cfg.frame) % cfg.hop == 0)
        self.completed = done
        which = np.flatnonzero(done)
        if len(which):  # every stream that completed a frame at once: one FFT call, not one per robot
            oldest = (self.count[which] % cfg.frame)[:, None]  # (d, 1) the ring's oldest sample
            pos = (oldest + self.order[None, :]) % cfg.frame  # (d, L) oldest first
            frames = self.ring[which[:, None], pos]  # (d, L, C)
            self.last[which] = segment_features(frames, cfg)
            self.known[which] = True
        return self.last.copy(), self.known.copy()


def log_frames(rows, config: SpectralConfig, *, transform=None, chunk_frames: int = CHUNK_FRAMES) -> np.ndarray:
    """Frame features of a whole log read a chunk at a time: a 10-hour log at 100 Hz is never held whole.

    Args:
        rows: ``(T, C)`` samples, or anything sliced like them (a memory-mapped file).
        config: Sizes and channels.
        transform: Applied to each chunk of samples first (the model's input normalisation).
        chunk_frames: Frames per read.

    Returns:
        ``(N, F)`` float32, equal to ``frame_features(transform(rows[:]), config)``.
    """
    n = len(rows)
    ends = frame_ends(n, config)
    out = np.empty((len(ends), config.width), np.float32)
    for a in range(0, len(ends), chunk_frames):
        e = ends[a : a + chunk_frames]
        lo, hi = int(e[0]) - config.frame + 1, int(e[-1]) + 1
        x = np.asarray(rows[lo:hi], np.float32)
        if transform is not None:
            x = transform(x)
        out[a : a + len(e)] = frame_features(x, config)
    return out


def log_summaries(rows, config: SpectralConfig, *, transform=None) -> np.ndarray:
    """``(N, 2F)`` float32: the mean and spread of the last ``config.window`` frames at every frame of a log."""
    return summary_windows(log_frames(rows, config, transform=transform), frames_per_window=config.window)


def stacked_frames(frames: np.ndarray, which: np.ndarray, window: int) -> np.ndarray:
    """The ``window`` frames ending at each frame of ``which``, oldest first, flattened: ``(len(which), window·F)``.

    A window short of frames at a log's start repeats its first frame: the streaming step fills its ring with the
    first frame it sees, so both compute the same input.
    """
    idx = window_index(which, window)  # (n, W)
    return np.asarray(frames[idx.reshape(-1)], np.float32).reshape(len(idx), -1)


def window_index(which: np.ndarray, window: int) -> np.ndarray:
    """``(n, window)`` the frames of each window :func:`stacked_frames` stacks, oldest first (the first frame repeated
    where a log's start leaves the window short)."""
    return np.maximum(np.asarray(which, np.int64)[:, None] - window + 1 + np.arange(window)[None, :], 0)


def last_frame(steps: np.ndarray, config: SpectralConfig) -> np.ndarray:
    """``(L,)`` index of the last frame complete at or before each step (``-1`` before the first frame)."""
    return np.where(steps >= config.frame - 1, (steps - (config.frame - 1)) // config.hop, -1)


class SpectralSteps:
    """A log's per-step stage-2 inputs from its frames: each step holds the last ``config.window`` frames complete at
    or before it (zeros before the first), computed for the rows sliced only.

    Supports ``len``, ``shape`` and ``[start:stop]`` along the first axis, as the passes read features. A 10-hour
    log's frames are 5 Hz rows; stacked and expanded to 100 Hz steps they would be 140 times the memory.
    """

    def __init__(self, frames: np.ndarray, n_samples: int, config: SpectralConfig) -> None:
        self.frames, self.config = frames, config
        self.shape = (n_samples, config.step_width)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, key: slice) -> np.ndarray:
        if not isinstance(key, slice) or key.step not in (None, 1):
            raise TypeError("SpectralSteps supports [start:stop] slices only")
        start, stop, _ = key.indices(self.shape[0])
        return self.at(np.arange(start, max(start, stop)))

    def at(self, steps: np.ndarray) -> np.ndarray:
        """The inputs of ``steps`` (ascending), ``(len(steps), window·F)``, without those of the steps between."""
        cfg = self.config
        which = last_frame(np.asarray(steps, np.int64), cfg)  # (L,)
        out = np.zeros((len(which), self.shape[1]), np.float32)
        known = which >= 0
        if known.any():
            lo = max(int(which[known][0]) - cfg.window + 1, 0)
            block = np.asarray(self.frames[lo : int(which[-1]) + 1], np.float32)  # read only what is used
            distinct, inverse = np.unique(which[known] - lo, return_inverse=True)
            out[known] = stacked_frames(block, distinct, cfg.window)[inverse]  # each frame's window stacked once
        return out

    def release(self) -> None:
        """Give back the pages reads of its memory-mapped frames put in the resident set (:func:`drop_pages`): a
        pass that copies what it reads calls it once done with the log, so a fleet's frames are not held twice."""
        drop_pages(self.frames)

    def frame_rows(self, start: int, stop: int) -> np.ndarray:
        """The steps of ``[start, stop)`` at which a frame completes: one row per distinct input."""
        cfg = self.config
        first = max(start, cfg.frame - 1)
        first += (cfg.hop - (first - (cfg.frame - 1)) % cfg.hop) % cfg.hop
        return np.arange(first, stop, cfg.hop, dtype=np.int64)


def summary_windows(frames: np.ndarray, *, frames_per_window: int, ends: Sequence[int] | None = None) -> np.ndarray:
    """Mean and spread over the last ``frames_per_window`` frames ending at each of ``ends`` (default: every
    frame): ``(W, 2F)``. A window short of frames at a log's start uses those it has."""
    n = len(frames)
    ends_arr = np.arange(n) if ends is None else np.asarray(ends, np.int64)
    c1 = np.concatenate([np.zeros((1, frames.shape[1])), np.cumsum(frames, axis=0, dtype=np.float64)])
    c2 = np.concatenate([np.zeros((1, frames.shape[1])), np.cumsum(np.square(frames, dtype=np.float64), axis=0)])
    hi = ends_arr + 1
    lo = np.maximum(hi - frames_per_window, 0)
    k = (hi - lo)[:, None]
    mean = (c1[hi] - c1[lo]) / k
    var = np.maximum((c2[hi] - c2[lo]) / k - mean**2, 0.0)
    return np.concatenate([mean, np.sqrt(var)], axis=1).astype(np.float32)
