"""Label files: one row per segment, as CSV, Parquet or JSON; exported and imported (all or nothing)."""

from __future__ import annotations

import io
import json
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pandas loads where a table is read: commands that read none start sooner
    import pandas as pd

from .check_rows import CHECK_COLUMNS, check_of_row, classifier_versions, given
from .errors import LabelError
from .label_studio import is_label_studio, label_studio_frame
from .labels import add_segment, labelled_as
from .limits import MAX_LABEL_FILE_BYTES, MAX_LABEL_LINE_BYTES, MAX_LABEL_NESTING, MAX_LABEL_ROWS, MAX_NAME_CHARS
from .logs import LogInfo, Segment
from .new_files import new_file
from .row_logs import logs_by, row_log
from .terrain_rows import renamed_to

COLUMNS = (
    "log",
    "source_file",
    "start_s",
    "end_s",
    "start_sample",
    "end_sample",
    "terrain",
    "author",
    "source",
    "created_at",
    "updated_at",
)
FORMATS = {".csv": "csv", ".parquet": "parquet", ".json": "json"}


def segments_frame(segments: list[Segment], logs: dict[int, LogInfo]) -> pd.DataFrame:
    """A table of segments with times in seconds (from the log's start) and in samples."""
    import pandas as pd

    rows = []
    for s in segments:
        log = logs[s.log_id]
        rows.append(
            (
                log.name,
                log.source_path,
                s.start / log.rate_hz,
                s.stop / log.rate_hz,
                s.start,
                s.stop,
                s.terrain,
                s.author,
                s.source,
                s.created_at,
                s.updated_at,
            )
        )
    return pd.DataFrame(rows, columns=list(COLUMNS))


def file_format(path: Path) -> str:
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise LabelError(f"{path}: unknown label file type {path.suffix!r}; use .csv, .parquet or .json")
    return fmt


# A spreadsheet runs a cell that starts with one of these as a formula (OWASP's CSV injection list).
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def neutralise_formulas(frame: pd.DataFrame) -> pd.DataFrame:
    """A copy where every text cell a spreadsheet would run as a formula starts with ``'``, which it shows as text.

    Log names, file paths and authors are data: a log named ``=HYPERLINK(...)`` must not run when a colleague opens
    the exported CSV. Numbers are left alone (``-0.5`` is a number, not a formula).
    """
    import pandas as pd

    out = frame.copy()
    for column in out.columns:
        if not pd.api.types.is_numeric_dtype(out[column]):
            out[column] = out[column].map(
                lambda v: "'" + v if isinstance(v, str) and v.startswith(FORMULA_START) else v
            )
    return out


def restore_formulas(frame: pd.DataFrame) -> pd.DataFrame:
    """Undo :func:`neutralise_formulas`, so a label file exported as CSV imports back to the same names."""
    import pandas as pd

    for column in frame.columns:
        if pd.api.types.is_numeric_dtype(frame[column]):
            continue
        text = frame[column].astype("string")  # vectorised on Arrow strings: no Python object per cell
        quoted = (text.str.startswith("'") & text.str[1:2].isin(FORMULA_START)).fillna(False).astype(bool)
        if quoted.any():  # only those cells change: the rest keep their storage
            frame.loc[quoted, column] = text[quoted].str[1:]
    return frame


def write_frame(frame: pd.DataFrame, path: Path) -> Path:
    """Write a table as a new CSV, Parquet or JSON (records) file, chosen by the file's suffix.

    Raises:
        WorkbenchError: ``path`` exists, is a link, or its folder is missing (``new_files``): nothing is replaced.
    """
    fmt = file_format(path)
    with new_file(Path(path)) as tmp:
        if fmt == "csv":
            neutralise_formulas(frame).to_csv(tmp, index=False)
        elif fmt == "parquet":
            frame.to_parquet(tmp, index=False)
        else:
            frame.to_json(tmp, orient="records", indent=1)
    return path


def read_frame(path: Path, *, max_rows: int = MAX_LABEL_ROWS, logs: list[LogInfo] | None = None) -> pd.DataFrame:
    """A label file as a table, its size checked before it is decoded (``sessions/limits.py``). With ``logs``, a
    Label Studio export (JSON) is read too, its regions resolved against them (``label_studio.py``).

    Raises:
        LabelError: Unreadable, or over a limit: the file's bytes, a Parquet file's rows or decoded row groups, a
            JSON file's nesting.
    """
    import pandas as pd

    fmt = file_format(path)
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise LabelError(f"{path}: cannot read label file ({exc.strerror or exc})") from None
    if size > MAX_LABEL_FILE_BYTES:
        raise LabelError(f"{path}: {size:,} bytes, over the limit of {MAX_LABEL_FILE_BYTES:,} for a label file")
    try:
        if fmt == "csv":
            _check_csv_rows(path, max_rows)
            with warnings.catch_warnings():  # a library's warning is no message for a person: errors name the row
                warnings.simplefilter("ignore")
                # every cell as text: a terrain named NA, null or NaN is a name, not a missing value; numbers are
                # read by parse_rows, which names the first bad cell's row
                # Arrow strings: 4.9 million rows as Python strings peaked at 0.9 GB
                frame = pd.read_csv(
                    path, dtype="string[pyarrow]", keep_default_na=False, na_values=[], engine="pyarrow"
                )
            frame = restore_formulas(frame)
        elif fmt == "parquet":
            _check_parquet(path, max_rows)
            frame = pd.read_parquet(path)
        else:
            text = path.read_text(encoding="utf-8")
            data = _check_json(path, text, label_studio=logs is not None)
            if logs is not None and is_label_studio(data):
                frame = label_studio_frame(data, logs, path=path)
            else:
                frame = pd.read_json(io.StringIO(text), orient="records")
    except LabelError:
        raise
    except Exception as exc:
        raise LabelError(f"{path}: cannot read label file ({type(exc).__name__}: {exc})") from None
    frame = frame.reset_index(drop=True)  # row i is line i + 2, whatever index a Parquet file stored
    _check_names(frame, path)
    return frame


NAMED_COLUMNS = ("log", "terrain", "author", "guess", "kind")
ONE_LINE_COLUMNS = ("terrain", "guess", "kind")  # names of terrains and kinds: one line of text each


def _check_names(frame: pd.DataFrame, path: Path) -> None:
    """Refuse a file naming a log, terrain or author longer than ``MAX_NAME_CHARS``, naming its first such row."""
    for column in NAMED_COLUMNS:
        if column not in frame.columns or frame[column].dtype.kind in "biuf":
            continue
        text = frame[column].astype("string")
        lengths = text.str.len().fillna(0).to_numpy()  # (rows,)
        over = (lengths > MAX_NAME_CHARS).nonzero()[0]
        if len(over):
            raise LabelError(
                f"{path}: {_where(frame, int(over[0]))}: {column} is {int(lengths[over[0]]):,} characters long; a "
                f"name is at most {MAX_NAME_CHARS}; nothing was imported"
            )
        if column in ONE_LINE_COLUMNS:  # a log's name is its file's, whatever it holds; a terrain's is one line
            control = text.str.contains(CONTROL, regex=True).fillna(False).to_numpy().nonzero()[0]
            if len(control):
                what = "the terrain name" if column == "terrain" else f"the {column}"
                raise LabelError(
                    f"{path}: {_where(frame, int(control[0]))}: {what} holds a control character (a "
                    "newline, an escape); a name is one line of text; nothing was imported"
                )


CONTROL = r"[\x00-\x1f\x7f-\x9f]"  # what a terminal acts on: C0, DEL and C1


def _where(frame: pd.DataFrame, i: int) -> str:
    """How messages name the ``i``-th row of a label file: its line, or a Label Studio task's region."""
    return str(frame["at"].iloc[i]) if "at" in frame.columns else f"row {i + 2}"


def _check_csv_rows(path: Path, max_rows: int) -> None:
    """Refuse a CSV with more rows than a label file may hold, counting lines before any is decoded (pandas took
    3.8 GB and minutes on 10 million rows)."""
    import numpy as np

    lines, open_line = 0, 0  # newlines so far; bytes since the last one
    with open(path, "rb") as f:
        while block := f.read(1 << 22):
            ends = np.flatnonzero(np.frombuffer(block, np.uint8) == 10)  # (n,) where each line of the block ends
            # (n + 1,) the bytes of each line the block holds a part of: the open one first, the unfinished one last
            gaps = np.diff(np.concatenate([[-1 - open_line], ends, [len(block)]])) - 1
            if gaps.max() > MAX_LABEL_LINE_BYTES:
                row = lines + 1 + int(np.flatnonzero(gaps > MAX_LABEL_LINE_BYTES)[0])  # line 1 is the header
                raise LabelError(
                    f"{path}: row {row} is longer than {MAX_LABEL_LINE_BYTES:,} bytes; a row of a label file holds "
                    f"names of at most {MAX_NAME_CHARS} characters and a few numbers; nothing was imported"
                )
            lines += len(ends)
            open_line = int(gaps[-1])
            if lines > max_rows + 1:
                raise LabelError(f"{path}: more than {max_rows:,} rows, the limit for a label file; split it")


def _check_parquet(path: Path, max_rows: int) -> None:
    """Refuse a Parquet file whose metadata claims more rows or decoded bytes than a label file may hold."""
    import pyarrow.parquet as pq

    meta = pq.ParquetFile(path).metadata  # the footer only: no row is decoded
    if meta.num_rows > max_rows:
        raise LabelError(f"{path}: the file claims {meta.num_rows:,} rows, over the limit of {max_rows:,} for labels")
    decoded = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
    if decoded > MAX_LABEL_FILE_BYTES:
        raise LabelError(
            f"{path}: its row groups decode to {decoded:,} bytes, over the limit of {MAX_LABEL_FILE_BYTES:,}"
        )


def _check_json(path: Path, text: str, *, label_studio: bool = False) -> object:
    """Refuse JSON that is not a list of flat records (or, when ``label_studio``, a Label Studio export), before
    pandas reads it (deep nesting included). Returns the parsed JSON."""
    try:
        data = json.loads(text)
    except RecursionError:
        raise LabelError(
            f"{path}: JSON nested deeper than the parser allows; a label file is a list of records"
        ) from None
    if label_studio and is_label_studio(data):
        return data
    flat = isinstance(data, list) and all(
        isinstance(r, dict) and not any(isinstance(v, dict | list) for v in r.values()) for r in data
    )
    if not flat:
        raise LabelError(
            f"{path}: JSON nested deeper than {MAX_LABEL_NESTING} levels; a label file is a list of records of plain "
            'values ([{"log": ..., "terrain": ..., "start_s": ..., "end_s": ...}])'
            + (" or a Label Studio export (tasks with data and annotations)" if label_studio else "")
        )
    return data


@dataclass(frozen=True)
class Row:
    """One row of a label file, resolved: its line in the file, log, range in samples, terrain and author."""

    line: int
    where: str  # how messages name it: "row 7", or a Label Studio region's task and number
    log: LogInfo
    start: int
    stop: int
    terrain: str
    author: str | None


def unlabelled_rows(frame: pd.DataFrame) -> tuple[pd.DataFrame, list[int]]:
    """The rows whose terrain is filled in, and the line numbers of those whose terrain is empty: a row of
    ``workbench suggest``'s file nobody has labelled yet (its terrain column left blank) is no label, and not an
    error either."""
    if "terrain" not in frame.columns:
        return frame, []
    blank = frame["terrain"].isna().to_numpy() | (frame["terrain"].astype("string").str.strip() == "").fillna(True)
    blank = np.asarray(blank, bool)
    return frame[~blank], [int(i) + 2 for i in np.flatnonzero(blank)]  # the index keeps each row's line


def parse_rows(
    frame: pd.DataFrame,
    logs: list[LogInfo],
    terrains: list[str],
    *,
    path: Path,
    renamed: Mapping[str, str] | None = None,
) -> list[Row]:
    """Every row of a label file resolved against the session, or a ``LabelError`` naming the first bad row.

    Rows name their log by ``log`` (name) and give ``start_sample``/``end_sample`` or ``start_s``/``end_s``.
    ``renamed``: names the session's terrains gave up, to their names now (``terrain_rows.renamed_to``), for the
    refusal of a file that uses one.
    """
    missing = {"log", "terrain"} - set(frame.columns)
    if missing or not (
        {"start_sample", "end_sample"} <= set(frame.columns) or {"start_s", "end_s"} <= set(frame.columns)
    ):
        raise LabelError(f"{path}: label file needs columns log, terrain and start_sample/end_sample or start_s/end_s")
    has_samples = {"start_sample", "end_sample"} <= set(frame.columns)
    has_seconds = {"start_s", "end_s"} <= set(frame.columns)
    has_source = "source_file" in frame.columns
    by_name, by_source = logs_by(logs)
    out = []
    for index, row in zip(frame.index, frame.itertuples(index=False), strict=True):
        i = int(index) + 2  # line 1 is the header; a row left out (unlabelled_rows) keeps the others' lines
        where = str(row.at) if "at" in frame.columns else f"row {i}"
        source = str(row.source_file) if has_source and given(row.source_file) else None
        log = row_log(by_name, by_source, str(row.log), source, path=path, where=where)
        if not given(row.terrain):
            raise LabelError(f"{path}: {where}: terrain is empty; every row names its terrain; nothing was imported")
        if str(row.terrain) not in terrains and str(row.terrain) in (renamed or {}):
            raise LabelError(
                f"{path}: {where}: terrain {row.terrain!r} was renamed {renamed[str(row.terrain)]!r} in this session; "
                "nothing was imported (write its name now in the file)"
            )
        if str(row.terrain) not in terrains:
            raise LabelError(
                f"{path}: {where}: unknown terrain {row.terrain!r}; nothing was imported (add it with `workbench "
                "terrains SESSION add NAME`, or import with --create-terrains)"
            )
        if has_samples and (not has_seconds or given(row.start_sample)):
            start = _whole(row.start_sample, "start_sample", path=path, where=where)
            stop = _whole(row.end_sample, "end_sample", path=path, where=where)
        else:
            start = _sample_at(row.start_s, "start_s", log.rate_hz, path=path, where=where)
            stop = _sample_at(row.end_s, "end_s", log.rate_hz, path=path, where=where)
        who = str(row.author) if "author" in frame.columns and given(row.author) else None
        out.append(Row(i, where, log, start, stop, str(row.terrain), who))
    return out


@dataclass(frozen=True)
class LabelImport:
    """What importing a label file did.

    Attributes:
        segments: The segments as stored after each row that labelled anything new.
        rows: The rows with a terrain (each a label).
        already: Of those, rows whose span the session labelled with that terrain already (nothing changed).
        blank: Line numbers of the rows left out because their terrain is empty (a suggestion nobody labelled).
        checks: Checks of a classifier added (rows of a ``workbench suggest`` file).
        checks_already: Rows that checked a piece, version and kind checked before (counted once).
        checks_unrecorded: Rows filled in whose piece the session never wrote in a ``suggest`` file for that version
            (a file from elsewhere, or written before the session kept that record): labels, not checks.
    """

    segments: tuple[Segment, ...]
    rows: int
    already: int = 0
    blank: tuple[int, ...] = ()
    checks: int = 0
    checks_already: int = 0
    checks_unrecorded: int = 0


def import_rows(
    conn, frame: pd.DataFrame, logs: list[LogInfo], terrains: list[str], *, path: Path, author: str
) -> LabelImport:
    """Add every row as a segment inside the caller's transaction; any bad row refuses the whole file.

    A row whose span already holds its terrain changes nothing (a file imported twice adds nothing). A file written
    by ``workbench suggest`` (columns ``guess``, ``kind`` and ``classifier``) is also a set of checks: each row
    filled in keeps what that classifier guessed there (``checks.py``), once per piece, version and kind, as a
    label made in the page does."""
    out, already, checks = [], 0, [0, 0, 0]
    versions = classifier_versions(conn) if set(frame.columns) >= CHECK_COLUMNS else None
    for row in parse_rows(frame, logs, terrains, path=path, renamed=renamed_to(conn)):
        try:
            if versions is not None:  # checked before its label: a forged row refuses the file
                check_of_row(conn, frame.loc[row.line - 2], row, versions, author=row.author or author, counts=checks)
            if labelled_as(conn, row.log.id, row.start, row.stop, row.terrain):
                already += 1
                continue
            out.append(
                add_segment(
                    conn,
                    log_id=row.log.id,
                    start=row.start,
                    stop=row.stop,
                    terrain=row.terrain,
                    author=row.author or author,
                    source="import",
                    kind="import",
                )
            )
        except LabelError as exc:
            raise LabelError(f"{path}: {row.where}: {exc}; nothing was imported") from None
    rows = len(out) + already
    return LabelImport(
        tuple(out), rows, already, checks=checks[0], checks_already=checks[1], checks_unrecorded=checks[2]
    )


def import_reference_rows(conn, frame: pd.DataFrame, logs: list[LogInfo], terrains: list[str], *, path: Path) -> int:
    """Replace the reference truth of every log the file names with its rows, inside the caller's transaction.

    Reference truth is for evaluation only: it never becomes labels, and labels never become it. Rows of one log
    must not overlap. Returns the rows written.
    """
    rows = parse_rows(frame, logs, terrains, path=path, renamed=renamed_to(conn))
    by_log: dict[int, list[Row]] = {}
    for row in rows:
        if not 0 <= row.start < row.stop <= row.log.n_samples:
            raise LabelError(
                f"{path}: {row.where}: [{row.start}, {row.stop}) is not inside log {row.log.name!r} "
                f"(samples 0 to {row.log.n_samples}); nothing was imported"
            )
        by_log.setdefault(row.log.id, []).append(row)
    for log_rows in by_log.values():
        log_rows.sort(key=lambda r: r.start)
        for a, b in pairwise(log_rows):
            if b.start < a.stop:
                raise LabelError(f"{path}: {b.where}: overlaps {a.where} of the same log; nothing was imported")
    for log_id, log_rows in by_log.items():
        conn.execute("DELETE FROM reference WHERE log_id = ?", (log_id,))
        conn.executemany(
            "INSERT INTO reference (log_id, start, stop, terrain) VALUES (?, ?, ?, ?)",
            [(log_id, r.start, r.stop, r.terrain) for r in log_rows],
        )
    return len(rows)


def _number(value: object, column: str, *, path: Path, where: str) -> float:
    """A finite number from a cell, or a ``LabelError`` naming the file, the row and the column."""
    if not given(value):
        raise LabelError(f"{path}: {where}: {column} is empty; nothing was imported")
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise LabelError(f"{path}: {where}: {column} is {value!r}, not a number; nothing was imported") from None
    if math.isnan(x):
        raise LabelError(f"{path}: {where}: {column} is {value!r}, not a number; nothing was imported")
    if not math.isfinite(x):
        raise LabelError(f"{path}: {where}: {column} is {x!r}, not a finite number; nothing was imported")
    return x


def _sample_at(value: object, column: str, rate_hz: float, *, path: Path, where: str) -> int:
    """The sample at a time in seconds from a cell, or a ``LabelError`` naming the value as the file gives it."""
    x = _number(value, column, path=path, where=where)
    if not abs(x * rate_hz) <= 2**62:  # 1e308 s is a finite number of seconds, and no sample of any log
        raise LabelError(f"{path}: {where}: {column} is {x!r}, out of range; nothing was imported")
    return round(x * rate_hz)


def _whole(value: object, column: str, *, path: Path, where: str) -> int:
    """A sample index from a cell (a whole number, or seconds times the rate rounded), else a ``LabelError``."""
    x = _number(value, column, path=path, where=where)
    if abs(x) > 2**62:
        raise LabelError(f"{path}: {where}: {column} is {x!r}, out of range; nothing was imported")
    return round(x)
