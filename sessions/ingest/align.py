"""Put streams of different rates onto one time base.

Every channel is *held* (its latest sample at or before each grid time): causal, so nothing looks ahead, which is
what a robot running the model online sees. Duplicate timestamps collapse to the last sample. A stream silent for
longer than ``gap_samples`` of its own periods is in a gap: refused unless ``allow_gaps``, then recorded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import IngestError
from ..logs import Channel, Gap
from .base import IngestOptions, ParsedLog, Stream


@dataclass(frozen=True)
class AlignedLog:
    """A parsed log on one time base: ``data[i]`` is the state at ``t0 + i / rate_hz``."""

    parsed: ParsedLog
    t0: float
    rate_hz: float
    data: np.ndarray  # (T, C) float32
    channels: tuple[Channel, ...]
    gaps: tuple[Gap, ...]
    reference: tuple[tuple[int, int, str], ...]  # (start, stop, terrain) in samples
    stream_rates: dict[str, float]


def _dedupe(stream: Stream) -> tuple[np.ndarray, np.ndarray]:
    times, values = stream.times, stream.values
    keep = np.ones(len(times), dtype=bool)
    keep[:-1] = times[1:] != times[:-1]  # keep the last of equal stamps
    return times[keep], values[keep]


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


def align(parsed: ParsedLog, options: IngestOptions) -> AlignedLog:
    """Align a parsed log's streams onto one grid.

    The grid runs over the time all streams share, at ``options.target_rate`` or the fastest stream's median rate.

    Raises:
        IngestError: No stream has two samples, the streams share no time, or a gap was found and gaps are not
            allowed.
    """
    path = parsed.source_path
    streams: list[tuple[Stream, np.ndarray, np.ndarray, float]] = []
    for stream in parsed.streams:
        times, values = _dedupe(stream)
        if len(times) < 2:
            continue
        streams.append((stream, times, values, stream_rate(times)))
    if not streams:
        raise IngestError(path, "no stream has at least two samples")
    rate = float(options.target_rate or _snap(max(r for *_, r in streams)))
    start = max(float(t[0]) for _, t, _, _ in streams)
    stop = min(float(t[-1]) for _, t, _, _ in streams)
    if stop <= start:
        names = ", ".join(s.name for s, *_ in streams)
        raise IngestError(path, f"the streams ({names}) share no time span")
    n = int(np.floor((stop - start) * rate + 1e-9)) + 1
    grid = start + np.arange(n, dtype=np.float64) / rate  # (T,)

    width = sum(len(s.channels) for s, *_ in streams)
    data = np.empty((n, width), dtype=np.float32)
    channels: list[Channel] = []
    gaps: list[Gap] = []
    col = 0
    for stream, times, values, srate in streams:
        # (T,) latest sample at or before each grid time; stamps within 0.1 % of a period count as "at" it,
        # so float noise does not shift a stream that is sampled on the grid by one sample.
        idx = np.searchsorted(times, grid + 1e-3 / rate, side="right") - 1
        k = values.shape[1]
        data[:, col : col + k] = values[idx]
        col += k
        channels.extend(Channel(c, u, s) for c, u, s in zip(stream.channels, stream.units, stream.sources, strict=True))
        age = grid - times[idx]
        limit = options.gap_samples / srate
        for stale0, g1 in _runs(age > limit):
            last = int(idx[stale0])  # the last sample before the silence
            after = min(int(idx[g1 - 1]) + 1, len(times) - 1)  # the first one after it
            seconds = float(times[after] - times[last])
            # The gap is recorded from the grid point holding that last sample, not from when it went stale.
            g0 = int(np.searchsorted(grid, times[last], side="left"))
            reason = f"no data for {seconds:.3f} s ({seconds * srate:.0f} samples at {srate:.1f} Hz)"
            if not options.allow_gaps:
                raise IngestError(
                    path,
                    f"{reason} in stream {stream.name!r}; use --allow-gaps to record it as a gap",
                    where=f"t={grid[g0] - start:.3f} s",
                )
            gaps.append(Gap(g0, g1, stream.name, reason))
    if not np.isfinite(data).all():
        bad = np.argwhere(~np.isfinite(data))[0]
        raise IngestError(path, "non-finite value after alignment", where=f"channel {channels[bad[1]].name}")

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
    )
