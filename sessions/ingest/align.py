"""Put streams of different rates onto one time base.

Every channel is *held* (its latest sample at or before each grid time): causal, so nothing looks ahead, which is
what a robot running the model online sees. Duplicate timestamps collapse to the last sample; a stream that sends
each sample twice (about half its samples equal the one before in every channel) has the repeats dropped. A stream
silent for longer than ``gap_samples`` of its own periods is in a gap: refused unless ``allow_gaps``, then recorded.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import IngestError
from ..limits import MAX_GRID_GROWTH, MAX_RATE_HZ, MIN_GRID_ROWS
from ..logs import Channel, Gap
from ..rowfiles import NpyWriter
from .base import IngestOptions, ParsedLog, Stream


@dataclass(frozen=True)
class AlignedLog:
    """A parsed log on one time base: ``data[i]`` is the state at ``t0 + i / rate_hz``."""

    parsed: ParsedLog
    t0: float
    rate_hz: float
    data: np.ndarray | NpyWriter  # (T, C) float32, or the file it was written to (see ``align``'s allocate)
    channels: tuple[Channel, ...]
    gaps: tuple[Gap, ...]
    reference: tuple[tuple[int, int, str], ...]  # (start, stop, terrain) in samples
    stream_rates: dict[str, float]
    repeats: dict[str, int] = field(default_factory=dict)  # per stream, samples dropped as repeats of the last


def _dedupe(stream: Stream) -> tuple[np.ndarray, np.ndarray | None]:
    """Stamps with duplicates collapsed to the last sample, and which row of ``values`` each keeps (``None``: all,
    in order): the values themselves may be memory-mapped and are read later, a chunk at a time."""
    times = stream.times
    keep = np.ones(len(times), dtype=bool)
    keep[:-1] = times[1:] != times[:-1]  # keep the last of equal stamps
    if keep.all():
        return times, None
    return times[keep], np.flatnonzero(keep)


REPEAT_SHARE = 0.45  # consecutive samples equal in every channel this often: a sender that repeats each sample
REPEAT_PROBE = 20_000  # rows looked at to decide


def _repeated_rows(values, rows: np.ndarray | None, n: int) -> np.ndarray | None:
    """Rows (of the de-duplicated stamps) that repeat the previous sample in every channel, when a sender repeats
    its samples: some drivers publish each sample twice with a new stamp, which doubles the stream's apparent rate
    and halves the silence that counts as a gap. ``None`` when the stream does not do that."""

    def read(a: int, b: int) -> np.ndarray:  # de-duplicated rows a..b of the values, read in one slice
        if rows is None:
            return np.asarray(values[a:b])
        idx = rows[a:b]
        lo = int(idx[0])
        return np.asarray(values[lo : int(idx[-1]) + 1])[idx - lo]

    probe = read(0, min(n, REPEAT_PROBE))
    if len(probe) < 3 or np.ptp(probe, axis=0).max() == 0:  # a constant stream repeats by nature
        return None
    if (probe[1:] == probe[:-1]).all(axis=1).mean() < REPEAT_SHARE:
        return None
    repeat = np.zeros(n, dtype=bool)
    for a in range(1, n, ALIGN_ROWS):
        b = min(n, a + ALIGN_ROWS)
        block = read(a - 1, b)  # (b - a + 1, C): each row with the one before it
        repeat[a:b] = (block[1:] == block[:-1]).all(axis=1)
    return repeat


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, stop)`` of each run of True."""
    if not mask.any():
        return []
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist(), strict=True))


def _snap(rate: float) -> float:
    """A rate within 1e-4 of a whole number of Hz is that number: epoch-scale stamps (1.7e9 s) resolve to 0.2 µs,
    which turns 100 Hz into 100.000095 Hz; the grid's drift from snapping is under one sample per hour."""
    whole = round(rate)
    return float(whole) if whole > 0 and abs(rate - whole) < 1e-4 * rate else round(rate, 6)


def stream_rate(times: np.ndarray) -> float:
    """Median sample rate (Hz) of sorted, de-duplicated stamps."""
    return float(1.0 / np.median(np.diff(times)))


MIN_RATE_HZ = 1e-3  # slower "sensors" are stamps gone wrong (a column of dates, a unit error)
ALIGN_ROWS = 1 << 18  # grid rows aligned at a time: bounds the temporaries whatever the log's length


class DiscardRows:
    """Where a dry run aligns to: the shape is kept, the rows are checked and dropped (a dry run held a whole log)."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.shape = shape

    def __setitem__(self, key: slice, value: np.ndarray) -> None:
        pass


def align(
    parsed: ParsedLog, options: IngestOptions, *, allocate: Callable[[tuple[int, int]], np.ndarray] | None = None
) -> AlignedLog:
    """Align a parsed log's streams onto one grid.

    The grid runs over the time all streams share, at ``options.target_rate`` or the fastest stream's median rate.
    It is filled ``ALIGN_ROWS`` rows at a time, so memory holds the streams' stamps and one chunk, not the log.

    Args:
        parsed: The streams (their values may be memory-mapped).
        options: Rate and gap settings.
        allocate: Gives what the ``(T, C)`` float32 data is written into, row blocks in order (an ``NpyWriter``,
            so a long log goes straight to disk); default: an array in memory.

    Raises:
        IngestError: No stream has two samples, the streams share no time, a value is not finite, or a gap was
            found and gaps are not allowed.
    """
    path = parsed.source_path
    streams: list[tuple[Stream, np.ndarray, np.ndarray | None, float]] = []
    repeats: dict[str, int] = {}
    for stream in parsed.streams:
        times, rows = _dedupe(stream)
        repeat = _repeated_rows(stream.values, rows, len(times)) if len(times) > 2 else None
        if repeat is not None and repeat.any():
            keep = np.flatnonzero(~repeat)
            times, rows = times[keep], keep if rows is None else rows[keep]
            repeats[stream.name] = int(repeat.sum())
        if len(times) < 2:
            continue
        streams.append((stream, times, rows, stream_rate(times)))
    if not streams:
        raise IngestError(path, "no stream has at least two samples")
    rate = float(options.target_rate or _snap(max(r for *_, r in streams)))
    if options.target_rate and not 0 < rate <= MAX_RATE_HZ:
        raise IngestError(path, f"rate {rate:g} Hz is not between 0 and {MAX_RATE_HZ:g} Hz (sessions/limits.py)")
    if not MIN_RATE_HZ <= rate <= MAX_RATE_HZ:
        raise IngestError(
            path,
            f"sample rate {rate:g} Hz: the stamps are not those of a sensor log "
            f"(from {MIN_RATE_HZ:g} Hz, one sample every {1 / MIN_RATE_HZ:g} s, to {MAX_RATE_HZ:g} Hz)",
        )
    start = max(float(t[0]) for _, t, _, _ in streams)
    stop = min(float(t[-1]) for _, t, _, _ in streams)
    if stop <= start:
        names = ", ".join(s.name for s, *_ in streams)
        raise IngestError(path, f"the streams ({names}) share no time span")

    def grid(a: int, b: int) -> np.ndarray:
        return start + np.arange(a, b, dtype=np.float64) / rate  # (b - a,)

    def gap_error(stream: Stream, times: np.ndarray, last: int, after: int, srate: float) -> IngestError:
        seconds = float(times[after] - times[last])
        # the gap is reported from the grid point holding that last sample, not from when it went stale
        near = max(0, int(np.floor((times[last] - start) * rate)) - 1)
        g0 = near + int(np.searchsorted(grid(near, near + 3), times[last], side="left"))
        return IngestError(
            path,
            f"no data for {seconds:.3f} s ({seconds * srate:.0f} samples at {srate:.1f} Hz) in stream "
            f"{stream.name!r}; use --allow-gaps to record it as a gap",
            where=f"t={grid(g0, g0 + 1)[0] - start:.3f} s",
        )

    # Checked on the stamps before the grid is allocated: a stamp that jumps asks for a grid of any size. A step of
    # twice the limit and two grid periods is a gap however the grid falls; nearer ones are judged on the grid below.
    if not options.allow_gaps:
        for stream, times, _, srate in streams:
            steps = np.diff(times)  # (N - 1,)
            limit = 2.0 * options.gap_samples / srate + 2.0 / rate
            over = np.flatnonzero((steps > limit) & (times[1:] > start) & (times[:-1] < stop))
            if len(over):
                raise gap_error(stream, times, int(over[0]), int(over[0]) + 1, srate)
    span_rows = (stop - start) * rate + 1
    most = max(len(t) for _, t, _, _ in streams)
    if span_rows > max(MIN_GRID_ROWS, MAX_GRID_GROWTH * most):
        raise IngestError(
            path,
            f"{stop - start:,.1f} s at {rate:g} Hz is {span_rows:,.0f} samples from {most:,} read: more than "
            f"{MAX_GRID_GROWTH} per sample read (sessions/limits.py); a stamp that jumps, or a rate far above the "
            "sensors'; split the file where its time jumps, or choose a lower --rate",
        )
    n = int(np.floor((stop - start) * rate + 1e-9)) + 1

    def latest(times: np.ndarray, at: np.ndarray) -> np.ndarray:
        # latest sample at or before each grid time; stamps within 0.1 % of a period count as "at" it,
        # so float noise does not shift a stream that is sampled on the grid by one sample
        return np.searchsorted(times, at + 1e-3 / rate, side="right") - 1

    width = sum(len(s.channels) for s, *_ in streams)
    data = np.empty((n, width), np.float32) if allocate is None else allocate((n, width))
    channels = [Channel(*c) for s, *_ in streams for c in zip(s.channels, s.units, s.sources, strict=True)]
    stale: list[list[tuple[int, int]]] = [[] for _ in streams]  # per stream, runs of grid rows gone stale
    for a in range(0, n, ALIGN_ROWS):
        b = min(n, a + ALIGN_ROWS)
        at = grid(a, b)
        block = np.empty((b - a, width), np.float32)
        col = 0
        for s_i, (stream, times, rows, srate) in enumerate(streams):
            k = stream.values.shape[1]
            idx = latest(times, at)  # (b - a,)
            src = idx if rows is None else rows[idx]
            lo, hi = int(src.min()), int(src.max()) + 1
            block[:, col : col + k] = np.asarray(stream.values[lo:hi], np.float32)[src - lo]  # one read, gathered
            col += k
            for r0, r1 in _runs(at - times[idx] > options.gap_samples / srate):
                if stale[s_i] and stale[s_i][-1][1] == a + r0:  # a run that crosses the chunk boundary
                    stale[s_i][-1] = (stale[s_i][-1][0], a + r1)
                else:
                    stale[s_i].append((a + r0, a + r1))
        if not np.isfinite(block).all():
            bad = np.argwhere(~np.isfinite(block))[0]
            raise IngestError(path, "non-finite value after alignment", where=f"channel {channels[bad[1]].name}")
        data[a:b] = block
    gaps: list[Gap] = []
    for (stream, times, _, srate), runs in zip(streams, stale, strict=True):
        for stale0, g1 in runs:
            last = int(latest(times, grid(stale0, stale0 + 1))[0])  # the last sample before the silence
            after = min(int(latest(times, grid(g1 - 1, g1))[0]) + 1, len(times) - 1)  # the first one after it
            if not options.allow_gaps:
                raise gap_error(stream, times, last, after, srate)
            seconds = float(times[after] - times[last])
            # The gap is recorded from the grid point holding that last sample, not from when it went stale.
            near = max(0, int(np.floor((times[last] - start) * rate)) - 1)
            g0 = min(n, near + int(np.searchsorted(grid(near, near + 3), times[last], side="left")))
            reason = f"no data for {seconds:.3f} s ({seconds * srate:.0f} samples at {srate:.1f} Hz)"
            gaps.append(Gap(g0, g1, stream.name, reason))

    reference = []
    for t_a, t_b, terrain in parsed.reference:
        a = max(0, int(np.ceil((t_a - start) * rate - 1e-9)))
        b = min(n, int(np.ceil((t_b - start) * rate - 1e-9)))
        if b > a:
            reference.append((a, b, terrain))
    return AlignedLog(
        parsed=parsed,
        t0=start,
        rate_hz=rate,
        data=data,
        channels=tuple(channels),
        gaps=tuple(sorted(gaps, key=lambda g: (g.start, g.stream))),
        reference=tuple(reference),
        stream_rates={s.name: r for s, _, _, r in streams},
        repeats=repeats,
    )
