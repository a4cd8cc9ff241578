"""Value types describing what a session holds: logs, their channels and gaps, terrains, label segments."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Channel:
    """One column of a log's aligned array."""

    name: str
    unit: str
    source: str  # where it came from: "topic:field" for MCAP, "file:column" for CSV


@dataclass(frozen=True)
class Gap:
    """A stretch ``[start, stop)`` (samples) where a stream had no fresh data; the array holds its last value."""

    start: int
    stop: int
    stream: str
    reason: str


@dataclass(frozen=True)
class LogInfo:
    """A log in the session catalog. Its samples are a float32 ``[n_samples, len(channels)]`` array."""

    id: int
    name: str
    source_path: str
    format: str
    file: str
    n_samples: int
    rate_hz: float
    t0: float  # absolute time (s) of sample 0, on the source's clock
    channels: tuple[Channel, ...]
    gaps: tuple[Gap, ...] = ()
    reference_terrain: str | None = None
    ingested_at: str = ""
    info: Mapping[str, object] = field(default_factory=dict)

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @property
    def duration_s(self) -> float:
        return self.n_samples / self.rate_hz

    @property
    def channel_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.channels)

    def seconds(self, sample: int) -> float:
        """Time in seconds since the log's start of sample index ``sample``."""
        return sample / self.rate_hz

    def sample_at(self, seconds: float) -> int:
        """The sample index nearest ``seconds`` since the log's start, clipped to ``[0, n_samples]``."""
        return max(0, min(self.n_samples, round(seconds * self.rate_hz)))


@dataclass(frozen=True)
class Terrain:
    """A terrain class a segment can be labelled with."""

    id: int
    name: str
    color: str
    position: int


@dataclass(frozen=True)
class Segment:
    """A labelled stretch ``[start, stop)`` of a log, in samples."""

    id: int
    log_id: int
    start: int
    stop: int
    terrain: str
    author: str
    source: str  # "manual", "suggestion", "import", "seed", ...
    created_at: str
    updated_at: str

    @property
    def length(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class HistoryEntry:
    """One user action on labels and the segment rows it changed (``None`` = absent before/after)."""

    op_id: int
    at: str
    author: str
    kind: str
    undone_by: int | None
    changes: tuple[tuple[int, Mapping[str, object] | None, Mapping[str, object] | None], ...]
