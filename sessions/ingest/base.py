"""What readers hand to alignment: timed streams of numeric channels, plus the options that steer reading."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..rowfiles import FileRows
from .image_topics import CameraStream
from .poses import PoseTrack
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
    poses: tuple[PoseTrack, ...] = ()  # where the robot was, on the streams' clock (never a signal)


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
        tf_child: The ``/tf`` child frame a pose track follows (``[poses] tf_child``; default: the robot's base,
            ``base_link`` or another of ``poses.BASE_FRAMES``).
    """

    channels: tuple[ChannelSpec, ...] = ()
    ignore: tuple[str, ...] = ()
    rate_hz: float | None = None
    time_column: str | int | None = None
    time_unit: str | None = None
    header: bool | None = None
    columns: tuple[str, ...] = ()
    sample_rate_hz: float | None = None
    tf_child: str | None = None


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


def one_line_text(text: str) -> str:
    """A parser's message on one line (tomllib and json name the line and column in it)."""
    return " ".join(text.split())


TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}


def load_mapping(path: str | Path) -> Mapping:
    """Read a mapping file (``.toml`` or ``.json``).

    Raises:
        IngestError: The file is unreadable or has unknown keys or bad values.
    """
    import json
    import tomllib

    from ..errors import IngestError
    from ..limits import MAX_MAPPING_BYTES, MAX_MAPPING_CHANNELS, MAX_RATE_HZ

    path = Path(path)
    try:
        if (size := path.stat().st_size) > MAX_MAPPING_BYTES:
            raise IngestError(path, f"{size:,} bytes: a mapping file is at most {MAX_MAPPING_BYTES:,}")
        text = path.read_text(encoding="utf-8-sig")
        raw = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except RecursionError:
        raise IngestError(path, "cannot read mapping file: nested deeper than the parser allows") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise IngestError(path, f"cannot read mapping file: {one_line_text(str(exc))}") from None
    if not isinstance(raw, dict):
        raise IngestError(path, "mapping file must hold a table/object at the top")
    csv = raw.pop("csv", {}) or {}
    poses = raw.pop("poses", {}) or {}
    known = {"channels", "ignore", "rate_hz"}
    unknown = set(raw) - known
    csv_known = {"time_column", "time_unit", "header", "columns", "sample_rate_hz"}
    unknown |= {f"csv.{k}" for k in set(csv) - csv_known}
    unknown |= {f"poses.{k}" for k in set(poses) - {"tf_child"}} if isinstance(poses, dict) else set()
    if unknown:
        raise IngestError(path, f"unknown keys in mapping file: {', '.join(sorted(unknown))}")
    try:
        if not isinstance(csv, dict):
            raise ValueError("[csv] must be a table")
        if not isinstance(poses, dict) or not isinstance(poses.get("tf_child", ""), str):
            raise ValueError("[poses] must be a table, its tf_child a frame's name")
        listed = {k: raw.get(k, []) for k in ("channels", "ignore")} | {"csv.columns": csv.get("columns", [])}
        for label, value in listed.items():
            if not isinstance(value, list):
                raise ValueError(f"{label} must be a list")
            if len(value) > MAX_MAPPING_CHANNELS:
                raise ValueError(f"{len(value):,} {label}: a mapping declares at most {MAX_MAPPING_CHANNELS:,}")
        if not all(isinstance(c, dict) for c in listed["channels"]):
            raise ValueError("each [[channels]] entry must be a table")
        channels = tuple(
            ChannelSpec(
                source=str(c["source"]),
                field=str(c.get("field", "")),
                name=str(c.get("name", "")),
                unit=str(c.get("unit", "")),
            )
            for c in listed["channels"]
        )
        seen: set[tuple[str, str]] = set()
        for c in channels:
            if (c.source, c.field) in seen:
                where = c.source + (f" field {c.field}" if c.field else "")
                raise ValueError(f"channels: {where!r} is listed more than once (each source is read once)")
            seen.add((c.source, c.field))
        time_unit = csv.get("time_unit")
        if time_unit is not None and time_unit not in TIME_UNITS:
            raise ValueError(f"csv.time_unit must be one of {', '.join(TIME_UNITS)}, not {time_unit!r}")
        header = csv.get("header")
        if header is not None and not isinstance(header, bool):
            raise ValueError(f"csv.header must be true or false, not {header!r}")
        time_column = csv.get("time_column")
        if time_column is not None and (isinstance(time_column, bool) or not isinstance(time_column, str | int)):
            raise ValueError(f"csv.time_column must be a column name or a 0-based number, not {time_column!r}")
        rate = raw.get("rate_hz")
        sample_rate = csv.get("sample_rate_hz")
        for label, value in (("rate_hz", rate), ("csv.sample_rate_hz", sample_rate)):
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{label} must be a number, not {value!r}")
            if not 0 < float(value) <= MAX_RATE_HZ:
                raise ValueError(f"{label} = {value:g}: a rate is above 0 and at most {MAX_RATE_HZ:g} Hz")
        return Mapping(
            channels=channels,
            ignore=tuple(str(x) for x in listed["ignore"]),
            rate_hz=None if rate is None else float(rate),
            time_column=time_column,
            time_unit=time_unit,
            header=header,
            columns=tuple(str(x) for x in listed["csv.columns"]),
            sample_rate_hz=None if sample_rate is None else float(sample_rate),
            tf_child=poses.get("tf_child") or None,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise IngestError(path, f"bad mapping file: {exc}") from None
