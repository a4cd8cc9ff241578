"""Turn the paths a user gives into sources (one recording's files) and read each into parsed logs."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import IngestError
from .bag_reader import BAG_SUFFIXES, read_bag
from .base import IngestOptions, ParsedLog
from .csv_reader import BOREAL_RE, QCAT_RE, is_borealtc, is_qcat, read_borealtc, read_generic_csv, read_qcat
from .mcap_reader import TopicReport, read_mcap

LOG_SUFFIXES = (".mcap", ".csv", *BAG_SUFFIXES)
COMPRESSED_BAG_SUFFIXES = (".db3.zstd", ".mcap.zstd")  # a ROS 2 bag compressed file by file (compression_mode: file)


def _is_compressed_bag(path: Path) -> bool:
    return path.name.lower().endswith(COMPRESSED_BAG_SUFFIXES)


@dataclass(frozen=True)
class Source:
    """The files of one recording and how to read them."""

    format: str  # "mcap" | "bag" | "qcat" | "borealtc" | "csv"
    files: tuple[Path, ...]

    @property
    def path(self) -> Path:
        return self.files[0]

    @property
    def size(self) -> int:
        """Bytes in all its files."""
        return sum(f.stat().st_size for f in self.files)


def _expand(paths: list[Path]) -> list[Path]:
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(
                q for q in p.rglob("*") if q.is_file() and (q.suffix.lower() in LOG_SUFFIXES or _is_compressed_bag(q))
            )
            if not found:
                raise IngestError(p, "folder holds no .mcap, .bag, .db3 or .csv files")
            out.extend(found)
        elif p.exists():
            out.append(p)
        else:
            raise IngestError(p, "no such file")
    return out


def plan_sources(paths: list[str | Path]) -> tuple[list[Source], list[IngestError]]:
    """Group files into sources: BorealTC imu/pro pairs and QCAT raw/imu pairs become one source each.

    A BorealTC or QCAT file given alone brings its partner from the same folder. Returns the sources and the errors
    for paths that do not exist or are not logs.
    """
    sources: list[Source] = []
    errors: list[IngestError] = []
    seen: set[Path] = set()
    files: list[Path] = []
    for p in paths:
        try:
            files.extend(_expand([Path(p)]))
        except IngestError as exc:
            errors.append(exc)
    for f in files:
        key = f.resolve()
        if key in seen:
            continue
        suffix = f.suffix.lower()
        if suffix == ".mcap":
            group, fmt = [f], "mcap"
        elif suffix in BAG_SUFFIXES:
            group, fmt = [f], "bag"
        elif suffix == ".csv" and is_borealtc(f):
            m = BOREAL_RE.match(f.name)
            assert m is not None
            group = [q for q in (f.with_name(f"{k}_{m['run']}.csv") for k in ("imu", "pro")) if q.exists()]
            fmt = "borealtc"
        elif suffix == ".csv" and is_qcat(f):
            m = QCAT_RE.match(f.name)
            assert m is not None
            stem = f"{m['terrain']}_{m['speed']}_legSensors"
            group = [q for q in (f.with_name(f"{stem}_{k}.csv") for k in ("raw", "imu")) if q.exists()]
            fmt = "qcat"
        elif suffix == ".csv":
            group, fmt = [f], "csv"
        elif _is_compressed_bag(f):
            errors.append(
                IngestError(
                    f,
                    "a ROS 2 bag compressed file by file (zstd), which is not read here; decompress it first "
                    "(`ros2 bag decompress`, or `zstd -d` on each file and compression_mode removed from "
                    "metadata.yaml), then ingest the .db3 or .mcap",
                )
            )
            continue
        else:
            kind = f.suffix or "(none)"
            errors.append(IngestError(f, f"unsupported file type {kind!r}; expected .mcap, .bag, .db3 or .csv"))
            continue
        seen.update(q.resolve() for q in group)
        sources.append(Source(fmt, tuple(group)))
    return sources, errors


def read_source(
    source: Source, options: IngestOptions, *, on_bytes: Callable[[int], None] | None = None
) -> tuple[list[ParsedLog], list[TopicReport]]:
    """Read one source into parsed logs (QCAT files give one per trial).

    ``on_bytes`` hears how far into the source's files reading got (MCAP reports as it goes, CSV at the end).

    Raises:
        IngestError: For any problem with the files; nothing else escapes for bad input.
    """
    try:
        if source.format == "mcap":
            parsed, reports = read_mcap(source.path, options, on_bytes=on_bytes)
            return [parsed], reports
        if source.format == "bag":
            parsed, reports = read_bag(source.path, options, on_bytes=on_bytes)
            return [parsed], reports
        if source.format == "borealtc":
            logs = [read_borealtc(list(source.files), options)]
        elif source.format == "qcat":
            logs = read_qcat(list(source.files), options)
        else:
            logs = [read_generic_csv(source.path, options)]
        if on_bytes is not None:
            on_bytes(source.size)
        return logs, []
    except IngestError:
        raise
    except MemoryError:
        raise IngestError(source.path, "file too large to read into memory") from None
    except OSError as exc:
        raise IngestError(source.path, f"cannot read: {exc.strerror or exc}") from None
    except Exception as exc:
        raise IngestError(source.path, f"cannot read: {type(exc).__name__}: {exc}") from None
