"""Read CSV logs: the QCAT layout, the BorealTC layout, and generic time + numeric channel files."""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas loads where a table is read: commands that read none start sooner
    import pandas as pd

from ..errors import IngestError
from ..limits import MAX_CSV_LINE_BYTES
from .base import TIME_UNITS, IngestOptions, ParsedLog, Stream
from .csv_poses import csv_track, pose_columns
from .dead_reckoning import dead_reckoned
from .time_columns import PROBE_ROWS, TimeColumn, find_time_columns, judge_unit

# QCAT (CSIRO, DyRET robot): `{terrain}_{speed}_legSensors_{raw|imu}.csv`, the terrain given as an index.
QCAT_TERRAINS = ("concrete", "grass", "gravel", "mulch", "dirt", "sand")
QCAT_RE = re.compile(r"^(?P<terrain>[A-Za-z0-9]+)_(?P<speed>\d+)_legSensors_(?P<kind>raw|imu)\.csv$")
QCAT_TRIAL_COLUMN = 3  # columns 0..3 are bookkeeping, the 4th holds the trial number
QCAT_WIDTH = {"raw": 12, "imu": 10}
QCAT_DEFAULT_RATE_HZ = 100.0  # used only when a QCAT file has no time column
QCAT_FORCE_NAMES = tuple(f"{foot}/force.{a}" for foot in ("fr", "fl", "br", "bl") for a in "xyz")
QCAT_IMU_NAMES = (
    *(f"imu/linear_acceleration.{a}" for a in "xyz"),
    *(f"imu/angular_velocity.{a}" for a in "xyz"),
    *(f"imu/orientation.{a}" for a in "xyzw"),
)
QCAT_IMU_UNITS = ("m/s²",) * 3 + ("rad/s",) * 3 + ("1",) * 4

# BorealTC (Husky A200): `CLASS/imu_NN.csv` (100 Hz) and `CLASS/pro_NN.csv` (~6.5 Hz) on one clock.
BOREAL_RE = re.compile(r"^(?P<kind>imu|pro)_(?P<run>\d+)\.csv$")
BOREAL_HEADERS = {
    "imu": ["time", "wx", "wy", "wz", "ax", "ay", "az"],
    "pro": ["time", "curL", "curR", "velL", "velR"],
}
BOREAL_UNITS = {
    "wx": "rad/s",
    "wy": "rad/s",
    "wz": "rad/s",
    "ax": "m/s²",
    "ay": "m/s²",
    "az": "m/s²",
    "curL": "A",
    "curR": "A",
    "velL": "m/s",
    "velR": "m/s",
}

TIME_NAMES = ("time", "timestamp", "t", "stamp", "time_s", "sec", "seconds")


def _first_line(path: Path) -> str:
    with open(path, encoding="utf-8-sig", errors="replace", newline="") as f:
        return f.readline(1 << 16)


def is_borealtc(path: Path) -> bool:
    """A file named as BorealTC's (``imu_N.csv``, ``pro_N.csv``) whose header has a ``time`` column and at least half
    of its kind's channels, in any order: read by name, so a missing channel is refused by name rather than the
    file read as a generic CSV."""
    m = BOREAL_RE.match(path.name)
    if not m:
        return False
    header = {h.strip() for h in next(csv.reader([_first_line(path)]), [])}
    expected = BOREAL_HEADERS[m["kind"]]
    return "time" in header and 2 * len(header & set(expected[1:])) >= len(expected) - 1


def is_qcat(path: Path) -> bool:
    return QCAT_RE.match(path.name) is not None


def _check_text(path: Path, *, block: int = 1 << 20) -> None:
    """Refuse binary data and absurd lines before the parser holds them: a 2 GB line would be read whole."""
    line, run, offset = 1, 0, 0  # run: bytes of the current line so far

    def too_long(at_line: int) -> IngestError:
        return IngestError(
            path, f"a line longer than {MAX_CSV_LINE_BYTES >> 20} MiB: not a sensor CSV", where=f"line {at_line}"
        )

    with open(path, "rb") as f:
        while chunk := f.read(block):
            nul = chunk.find(b"\0")
            if nul >= 0:
                raise IngestError(path, "binary data (NUL bytes), not CSV text", where=f"byte {offset + nul}")
            breaks = np.flatnonzero(np.frombuffer(chunk, np.uint8) == ord("\n"))  # (n,)
            if len(breaks) == 0:
                run += len(chunk)
            else:
                lengths = np.diff(breaks, prepend=-1) - 1  # each line ending in this chunk
                lengths[0] += run
                over = np.flatnonzero(lengths > MAX_CSV_LINE_BYTES)
                if len(over):
                    raise too_long(line + int(over[0]))
                line += len(breaks)
                run = len(chunk) - int(breaks[-1]) - 1
            if run > MAX_CSV_LINE_BYTES:
                raise too_long(line)
            offset += len(chunk)


def _read_frame(path: Path, *, header: bool | None, names: tuple[str, ...] = ()) -> pd.DataFrame:
    """Read a CSV as strings, so that bad cells can be reported by row and column."""
    import pandas as pd

    if path.stat().st_size == 0:
        raise IngestError(path, "empty file")
    _check_text(path)
    first = next(csv.reader([_first_line(path)]), [])
    if header is None:
        header = any(_not_number(c) for c in first if c.strip())
    if names and len(names) > len(first):
        # pandas would make a column of each name (100,000 names on a 27 KB file: 142 s and 7.6 GB)
        raise IngestError(
            path, f"the mapping names {len(names):,} columns (csv.columns); the file's first line has {len(first):,}"
        )
    try:
        frame = pd.read_csv(
            path,
            header=0 if header else None,
            names=list(names) if names else None,
            dtype=str,
            keep_default_na=False,
            encoding="utf-8-sig",
            skipinitialspace=True,
            on_bad_lines="error",
        )
    except pd.errors.EmptyDataError:
        raise IngestError(path, "empty file") from None
    except pd.errors.ParserError as exc:
        raise IngestError(path, f"malformed CSV: {str(exc).strip()}") from None
    except UnicodeDecodeError as exc:
        raise IngestError(path, f"not UTF-8 text: {exc.reason}", where=f"byte {exc.start}") from None
    if frame.empty:
        raise IngestError(path, "no data rows")
    frame.columns = [str(c).strip() for c in frame.columns]
    frame.attrs["first_data_line"] = 2 if header else 1
    return frame


def _not_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return True
    return False


def _numeric(path: Path, frame: pd.DataFrame, columns: list[str], *, allow_gaps: bool) -> np.ndarray:
    """``(N, K)`` float64 of ``columns``; text is refused, empty/NaN/inf refused unless ``allow_gaps`` (then NaN)."""
    import pandas as pd

    line0 = frame.attrs.get("first_data_line", 2)
    out = np.empty((len(frame), len(columns)), dtype=np.float64)
    for j, col in enumerate(columns):
        raw = frame[col].str.strip()
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=np.float64)
        lower = raw.str.lower()
        special = raw.eq("") | lower.isin(["nan", "inf", "+inf", "-inf", "infinity", "-infinity", "+infinity"])
        text = np.isnan(values) & ~special.to_numpy()
        if text.any():
            i = int(np.argmax(text))
            raise IngestError(path, f"text {raw.iloc[i][:40]!r} in numeric column {col!r}", where=f"line {line0 + i}")
        bad = ~np.isfinite(values)
        if bad.any() and not allow_gaps:
            i = int(np.argmax(bad))
            what = "empty cell" if raw.iloc[i] == "" else f"{raw.iloc[i]!r}"
            raise IngestError(
                path,
                f"{what} in column {col!r} (use --allow-gaps to record it as a gap)",
                where=f"line {line0 + i}",
            )
        out[:, j] = values
    return out


def _times(path: Path, frame: pd.DataFrame, column: str, scale: float) -> np.ndarray:
    """Seconds from a time column; refuses gaps in time and time going backwards."""
    line0 = frame.attrs.get("first_data_line", 2)
    times = _numeric(path, frame, [column], allow_gaps=False)[:, 0] * scale
    back = np.flatnonzero(np.diff(times) < 0)
    if back.size:
        i = int(back[0]) + 1
        raise IngestError(
            path,
            f"time goes backwards in column {column!r} ({times[i]:.6g} after {times[i - 1]:.6g})",
            where=f"line {line0 + i}",
        )
    return times


def _stream(
    path: Path,
    name: str,
    times: np.ndarray,
    values: np.ndarray,
    cols: list[str],
    channels: tuple[str, ...],
    units: tuple[str, ...],
) -> Stream:
    keep = np.isfinite(values).all(axis=1)  # rows with NaN become holes, recorded as gaps by alignment
    return Stream(name, times[keep], values[keep], channels, units, tuple(f"{path.name}:{c}" for c in cols))


def read_borealtc(paths: list[Path], options: IngestOptions) -> ParsedLog:
    """One BorealTC run: ``imu_NN.csv`` and/or ``pro_NN.csv`` from one terrain folder."""
    streams = []
    notes: list[str] = []
    run = ""
    for path in sorted(paths, key=lambda p: p.name):
        m = BOREAL_RE.match(path.name)
        assert m is not None
        kind, run = m["kind"], m["run"]
        frame = _read_frame(path, header=True)
        expected = BOREAL_HEADERS[kind]
        missing = [c for c in expected if c not in frame.columns]
        if missing:
            raise IngestError(
                path,
                f"missing column{'s' * (len(missing) > 1)} {', '.join(missing)} (a BorealTC {kind} file has "
                f"{', '.join(expected)}, in any order)",
            )
        extra = [str(c) for c in frame.columns if c not in expected]
        if extra:
            notes.append(f"{path.name}: column{'s' * (len(extra) > 1)} {', '.join(extra)} not read (not BorealTC's)")
        cols = expected[1:]  # by name: the session's channels keep BorealTC's order whatever the file's
        times = _times(path, frame, "time", 1.0)
        values = _numeric(path, frame, cols, allow_gaps=options.allow_gaps)
        streams.append(
            _stream(
                path,
                kind,
                times,
                values,
                cols,
                tuple(f"{kind}/{c}" for c in cols),
                tuple(BOREAL_UNITS[c] for c in cols),
            )
        )
    terrain = paths[0].parent.name
    reckoned = dead_reckoned(streams)  # a Husky records no position: its wheels and gyro draw one
    return ParsedLog(
        name=f"{terrain}_{run}",
        source_path=str(paths[0]),
        files=tuple(str(p) for p in paths),
        format="borealtc",
        streams=tuple(streams),
        reference_terrain=terrain.lower(),
        notes=tuple(notes),
        poses=() if reckoned is None else (reckoned,),
    )


def _qcat_terrain(token: str) -> str:
    if token.isdigit() and int(token) < len(QCAT_TERRAINS):
        return QCAT_TERRAINS[int(token)]
    return token.lower()


def read_qcat(paths: list[Path], options: IngestOptions) -> list[ParsedLog]:
    """QCAT files of one terrain and speed (``_raw`` forces and/or ``_imu``); one log per trial."""
    per_kind: dict[str, tuple[Path, pd.DataFrame]] = {}
    m = None
    for path in paths:
        m = QCAT_RE.match(path.name)
        assert m is not None
        frame = _read_frame(path, header=options.mapping.header)
        width = QCAT_WIDTH[m["kind"]]
        if frame.shape[1] != QCAT_TRIAL_COLUMN + 1 + width:
            raise IngestError(
                path,
                f"expected {QCAT_TRIAL_COLUMN + 1 + width} columns (4 bookkeeping + {width} {m['kind']} values), "
                f"found {frame.shape[1]}",
            )
        per_kind[m["kind"]] = (path, frame)
    assert m is not None
    terrain, speed = _qcat_terrain(m["terrain"]), m["speed"]
    rate = options.mapping.sample_rate_hz or QCAT_DEFAULT_RATE_HZ
    trials: dict[int, list[Stream]] = {}
    for kind in ("raw", "imu"):  # forces first, then IMU, as QCAT's users stack them
        if kind not in per_kind:
            continue
        path, frame = per_kind[kind]
        cols = list(frame.columns)
        meta, signal = cols[: QCAT_TRIAL_COLUMN + 1], cols[QCAT_TRIAL_COLUMN + 1 :]
        trial = _numeric(path, frame, [meta[QCAT_TRIAL_COLUMN]], allow_gaps=False)[:, 0].astype(int)
        values = _numeric(path, frame, signal, allow_gaps=options.allow_gaps)
        time_col = next((c for c in meta if c.lower() in TIME_NAMES or "time" in c.lower()), None)
        names, units = (QCAT_FORCE_NAMES, ("N",) * 12) if kind == "raw" else (QCAT_IMU_NAMES, QCAT_IMU_UNITS)
        for k in np.unique(trial):
            rows = np.flatnonzero(trial == k)
            if time_col is not None:
                times = _times(path, frame.iloc[rows], time_col, TIME_UNITS[options.mapping.time_unit or "s"])
                times = times - times[0]
            else:
                times = np.arange(len(rows), dtype=np.float64) / rate
            trials.setdefault(int(k), []).append(
                _stream(path, "forces" if kind == "raw" else "imu", times, values[rows], signal, names, units)
            )
    stem = f"{terrain}_{speed}"
    return [
        ParsedLog(
            name=f"{stem}_trial{k}",
            source_path=str(paths[0]),
            files=tuple(str(p) for p in paths),
            format="qcat",
            streams=tuple(streams),
            reference_terrain=terrain,
        )
        for k, streams in sorted(trials.items())
    ]


def sniff_csv(path: Path) -> tuple[bool, int]:
    """Whether a CSV's first line is a header (any cell not a number), and how many columns it has."""
    first = next(csv.reader([_first_line(path)]), [])
    return any(_not_number(c) for c in first if c.strip()), len(first)


NO_TIME_HINT = (
    "name the time column with [csv] time_column = INDEX or NAME, or give [csv] sample_rate_hz = HZ when the rows "
    "are evenly sampled and hold no time (workbench ingest --dry-run prints a mapping to start from)"
)


def _guessed_time(path: Path, frame: pd.DataFrame, column: str, scale: float) -> np.ndarray:
    """Seconds from a column taken as time only because it comes first: refused with a hint when it is no time."""
    try:
        return _times(path, frame, column, scale)
    except IngestError as err:
        if "time goes backwards" not in err.reason:
            raise
        raise IngestError(
            path,
            f"no time column: the first column {column!r} is no time ({err.reason.split('(')[-1].rstrip(')')} at "
            f"{err.where}); {NO_TIME_HINT}",
        ) from None


def _coerced(column: pd.Series) -> np.ndarray:
    import pandas as pd

    return pd.to_numeric(column.str.strip(), errors="coerce").to_numpy(dtype=np.float64)


def _found_time(frame: pd.DataFrame, cols: list[str]) -> list[TimeColumn]:
    head = frame.iloc[:PROBE_ROWS]
    return find_time_columns([(str(c), _coerced(head[c])) for c in cols], lambda i: _coerced(frame[cols[i]]))


def _unit_of(frame: pd.DataFrame, column: str) -> str:
    """The unit of a time column nobody gave one for: an epoch unit when its first value reads as one, else s."""
    first = _coerced(frame[column].iloc[:1])
    return (judge_unit(float(first[0])) if len(first) and np.isfinite(first[0]) else None) or "s"


def read_generic_csv(path: Path, options: IngestOptions) -> ParsedLog:
    """A time column (or rows at ``sample_rate_hz``) plus numeric channels; names, time column and unit from the
    mapping where given. With none named, a column called time (``TIME_NAMES``) or one that steps like a clock
    (:mod:`.time_columns`) is the time; with neither, the first column is tried."""
    mapping = options.mapping
    frame = _read_frame(path, header=mapping.header, names=mapping.columns)
    cols = list(frame.columns)
    time_col: str | None
    guessed = False
    found: TimeColumn | None = None
    not_read: list[str] = []  # other columns that step like a clock: a ramp is no terrain signal
    notes: list[str] = []
    position = None
    if mapping.time_column is not None:
        tc = mapping.time_column
        if isinstance(tc, int):
            if not 0 <= tc < len(cols):
                raise IngestError(path, f"time column index {tc} is out of range ({len(cols)} columns)")
            time_col = cols[tc]
        elif tc in cols:
            time_col = tc
        else:
            raise IngestError(path, f"time column {tc!r} not found; columns: {', '.join(map(str, cols))}")
    else:
        time_col = next((c for c in cols if str(c).lower() in TIME_NAMES), None)
        if time_col is None and mapping.sample_rate_hz is None:
            clocks = [t for t in _found_time(frame, cols) if t.name not in mapping.ignore]
            if clocks:
                found, time_col = clocks[0], cols[clocks[0].index]
                not_read = [cols[t.index] for t in clocks[1:]]
                if not_read:
                    notes.append(
                        f"{len(clocks)} columns could be time: {'; '.join(t.describe() for t in clocks)}. Read "
                        f"{found.name!r} as time and not the others; name one with [csv] time_column to choose"
                    )
                else:
                    notes.append(f"time: {found.describe()}, found by its steady steps")
            else:
                time_col, guessed = cols[0], True
    unit = mapping.time_unit or (found.unit if found else _unit_of(frame, time_col) if time_col else "s")
    if mapping.channels:
        missing = [s.source for s in mapping.channels if s.source not in cols]
        if missing:
            raise IngestError(path, f"missing columns named in the mapping: {', '.join(missing)}")
        chans = [s.source for s in mapping.channels]
        names = tuple(s.name or s.source for s in mapping.channels)
        units = tuple(s.unit for s in mapping.channels)
    else:
        skip = {time_col, *not_read, *mapping.ignore}
        chans = [c for c in cols if c not in skip]
        if (position := pose_columns(frame, chans)) is not None:
            chans = [c for c in chans if c not in position[1]]
        names, units = tuple(str(c) for c in chans), ("",) * len(chans)
    if not chans:
        raise IngestError(path, "no channel columns besides the time column")
    if time_col is None:  # rows evenly sampled at the mapping's rate
        times = np.arange(len(frame), dtype=np.float64) / float(mapping.sample_rate_hz or 1.0)
    elif guessed:
        times = _guessed_time(path, frame, time_col, TIME_UNITS[unit])
    else:
        times = _times(path, frame, time_col, TIME_UNITS[unit])
    values = _numeric(path, frame, chans, allow_gaps=options.allow_gaps)
    poses = ()
    stream = _stream(path, path.stem, times, values, chans, names, units)
    if not mapping.channels and position is not None:
        track, said = csv_track(frame, times, position, source=path.name)
        poses, notes = (track,), [*notes, said]
    elif (reckoned := dead_reckoned([stream])) is not None:  # wheel speeds and a yaw rate, no position
        poses = (reckoned,)
    return ParsedLog(
        name=path.stem,
        source_path=str(path),
        files=(str(path),),
        format="csv",
        streams=(stream,),
        notes=tuple(notes),
        found_time=found,
        poses=poses,
    )
