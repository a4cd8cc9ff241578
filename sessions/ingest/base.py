"""What readers hand to alignment: timed streams of numeric channels, plus the options that steer reading."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..rowfiles import FileRows
from .image_topics import CameraStream
from .time_columns import TimeColumn


@dataclass(frozen=True)
class Stream:
    """Samples of one source (an MCAP topic, a CSV file) on its own clock.

    Attributes:
        name: Short name of the source, used as channel prefix ("imu", "fl").
        times: ``(N,)`` float64 seconds, non-decreasing.
        values: ``(N, K)`` float64: an array, or rows on disk (``FileRows``) read a block at a time.
        channels: ``K`` channel names (already prefixed).
        units: ``K`` units.
        sources: ``K`` origins ("topic:field" / "file:column").
    """

    name: str
    times: np.ndarray
    values: np.ndarray | FileRows
    channels: tuple[str, ...]
    units: tuple[str, ...]
    sources: tuple[str, ...]


@dataclass(frozen=True)
class ParsedLog:
    """One recording as read from its file(s), before alignment."""

    name: str
    source_path: str
    files: tuple[str, ...]
    format: str  # "mcap" | "qcat" | "borealtc" | "csv"
    streams: tuple[Stream, ...]
    reference_terrain: str | None = None
    # Reference truth as (start_s, stop_s, terrain), absolute on the streams' clock: for evaluation only.
    reference: tuple[tuple[float, float, str], ...] = ()
    notes: tuple[str, ...] = ()
    cameras: tuple[CameraStream, ...] = ()  # camera frames, kept beside the arrays
    found_time: TimeColumn | None = None  # a CSV's time column when the reader found it itself


@dataclass(frozen=True)
class ChannelSpec:
    """An explicit channel from a mapping file."""

    source: str  # MCAP topic, or CSV column name
    field: str = ""  # MCAP: dotted path into the message ("wrench.force.x", "feet[0].force.z"); CSV: unused
    name: str = ""  # channel name in the session; derived when empty
    unit: str = ""


@dataclass(frozen=True)
class Mapping:
    """How to read logs when inference is not enough (a TOML or JSON file; see README "Bring your own logs").

    Attributes:
        channels: Explicit channels; when given, only these are read.
        ignore: MCAP topics or CSV columns never used.
        rate_hz: Rate of the aligned time base (default: the fastest stream's median rate).
        time_column: CSV time column, by name or 0-based index.
        time_unit: Unit of the CSV time column: "s", "ms", "us" or "ns"; ``None``: judged by its first value (an
            epoch time in the unit that reads as a date since 2001, else seconds).
        header: Whether the CSV has a header row (None: detect).
        columns: CSV column names when it has no header.
        sample_rate_hz: Rate of CSV files with no time column (QCAT files without one).
    """

    channels: tuple[ChannelSpec, ...] = ()
    ignore: tuple[str, ...] = ()
    rate_hz: float | None = None
    time_column: str | int | None = None
    time_unit: str | None = None
    header: bool | None = None
    columns: tuple[str, ...] = ()
    sample_rate_hz: float | None = None


@dataclass(frozen=True)
class IngestOptions:
    """Options of one ingest call."""

    mapping: Mapping = field(default_factory=Mapping)
    rate_hz: float | None = None  # overrides mapping.rate_hz
    allow_gaps: bool = False
    gap_samples: float = 5.0  # a stream silent for more than this many of its own periods is in a gap
    camera_fps: float = 2.0  # most camera frames kept a second per image topic (0: none): terrain changes over seconds

    @property
    def target_rate(self) -> float | None:
        return self.rate_hz if self.rate_hz is not None else self.mapping.rate_hz


TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def load_mapping(path: str | Path) -> Mapping:
    """Read a mapping file (``.toml`` or ``.json``).

    Raises:
        IngestError: The file is unreadable or has unknown keys or bad values.
    """
    import json
    import tomllib

    from ..errors import IngestError

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
        raw = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise IngestError(path, f"cannot read mapping file: {exc}") from None
    if not isinstance(raw, dict):
        raise IngestError(path, "mapping file must hold a table/object at the top")
    csv = raw.pop("csv", {}) or {}
    known = {"channels", "ignore", "rate_hz"}
    unknown = set(raw) - known
    csv_known = {"time_column", "time_unit", "header", "columns", "sample_rate_hz"}
    unknown |= {f"csv.{k}" for k in set(csv) - csv_known}
    if unknown:
        raise IngestError(path, f"unknown keys in mapping file: {', '.join(sorted(unknown))}")
    try:
        channels = tuple(
            ChannelSpec(
                source=str(c["source"]),
                field=str(c.get("field", "")),
                name=str(c.get("name", "")),
                unit=str(c.get("unit", "")),
            )
            for c in raw.get("channels", [])
        )
        time_unit = csv.get("time_unit")
        if time_unit is not None and time_unit not in TIME_UNITS:
            raise ValueError(f"csv.time_unit must be one of {', '.join(TIME_UNITS)}, not {time_unit!r}")
        rate = raw.get("rate_hz")
        sample_rate = csv.get("sample_rate_hz")
        for label, value in (("rate_hz", rate), ("csv.sample_rate_hz", sample_rate)):
            if value is not None and not float(value) > 0:
                raise ValueError(f"{label} must be positive")
        return Mapping(
            channels=channels,
            ignore=tuple(str(x) for x in raw.get("ignore", [])),
            rate_hz=None if rate is None else float(rate),
            time_column=csv.get("time_column"),
            time_unit=time_unit,
            header=csv.get("header"),
            columns=tuple(str(x) for x in csv.get("columns", [])),
            sample_rate_hz=None if sample_rate is None else float(sample_rate),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise IngestError(path, f"bad mapping file: {exc}") from None
