"""Label Studio in and out: time-series tasks with ``timeserieslabels`` regions, one task per log.

Out: a tasks JSON (one task per log, the log's labels as an annotation), a CSV of each log's signals with a
``time`` column on the log's clock (``t0 + i / rate`` seconds, as the MCAP files), and the project's labeling config.
When every log's clock is Unix time the project's time axis shows dates and times, and region ``start``/``end`` are
milliseconds, as Label Studio keeps them on a date axis; otherwise both are seconds. Either way a region means the
same instant in Label Studio, Foxglove and the session.

In: Label Studio's JSON export of such a project (tasks with ``annotations``, each a ``result`` list). A task names
its log by ``data.log`` (ours), else by the file its time series came from (``walk_001.csv``, also with Label
Studio's upload prefix ``1a2b3c4d-walk_001.csv``). A region's times are read on the log's clock, else as seconds
from the log's start, else as milliseconds on its clock (what a project whose time column is a date gives), in that
order: the first reading that puts the region inside the log.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

import numpy as np

if TYPE_CHECKING:  # pandas loads where a table is read: commands that read none start sooner
    import pandas as pd

from .errors import LabelError
from .file_names import safe_file_name
from .ingest.time_columns import EPOCH_RANGE_S
from .logs import LogInfo, Segment, Terrain
from .new_files import check_new_target, new_file

CONTROL = "terrain"  # the TimeSeriesLabels control's name in the labeling config we write
OBJECT = "ts"  # the TimeSeries object's name
BLOCK = 1 << 16  # rows of a log written to its CSV at a time
UPLOAD_PREFIX = re.compile(r"^[0-9a-f]{8}-")  # Label Studio renames an uploaded file abc12345-NAME


def files_folder(out: Path) -> Path:
    """Where the signals and the labeling config go, beside the tasks file: ``ls.json`` -> ``ls-files/``."""
    return out.with_name(f"{out.stem}-files")


def log_csv_name(log: LogInfo) -> str:
    return safe_file_name(log.name, empty="log") + ".csv"


def on_dates(logs: Sequence[LogInfo]) -> bool:
    """Whether the project's time axis shows dates: every log's clock is Unix time and sampled at 1 kHz or less
    (d3, which parses it, reads milliseconds, not microseconds: faster samples would share a time)."""
    return bool(logs) and all(EPOCH_RANGE_S[0] <= x.t0 <= EPOCH_RANGE_S[1] and x.rate_hz <= 1000 for x in logs)


def labeling_config(terrains: Sequence[Terrain], channels: Sequence[str], *, dates: bool) -> str:
    """The project's labeling config: one label per terrain (in its colour), the channels on a time axis: dates
    parsed from the epoch seconds of the CSVs' time column when ``dates``, else seconds."""
    labels = "\n".join(f"    <Label value={quoteattr(t.name)} background={quoteattr(t.color)}/>" for t in terrains)
    series = "\n".join(f"    <Channel column={quoteattr(c)} legend={quoteattr(c)}/>" for c in channels)
    # d3 reads "%s.%L" as epoch seconds and milliseconds ("%f" it does not parse: Label Studio 1.23 says so)
    axis = 'timeFormat="%s.%L" timeDisplayFormat="%H:%M:%S.%L"' if dates else 'timeDisplayFormat=",.3f"'
    return (
        "<View>\n"
        f'  <TimeSeriesLabels name="{CONTROL}" toName="{OBJECT}">\n{labels}\n  </TimeSeriesLabels>\n'
        f'  <TimeSeries name="{OBJECT}" valueType="url" value="$csv" sep="," timeColumn="time" {axis}>\n'
        f"{series}\n  </TimeSeries>\n</View>\n"
    )


def region(segment: Segment, log: LogInfo, *, dates: bool) -> dict:
    """A segment as a Label Studio ``timeserieslabels`` region, its times on the log's clock: in milliseconds on a
    date axis (as Label Studio keeps them there), else in seconds."""
    scale = 1e3 if dates else 1.0
    return {
        "id": f"wb{segment.id}",
        "from_name": CONTROL,
        "to_name": OBJECT,
        "type": "timeserieslabels",
        "origin": "manual",
        "value": {
            "start": (log.t0 + segment.start / log.rate_hz) * scale,
            "end": (log.t0 + segment.stop / log.rate_hz) * scale,
            "instant": False,
            "timeserieslabels": [segment.terrain],
        },
    }


def write_label_studio(
    out: Path,
    logs: Sequence[LogInfo],
    segments: Sequence[Segment],
    terrains: Sequence[Terrain],
    samples: Callable[[LogInfo, int, int], np.ndarray],
    *,
    url_prefix: str | None = None,
) -> list[Path]:
    """Write Label Studio's import: the tasks file ``out``, and beside it a folder of each log's CSV and the config.

    Args:
        out: The tasks JSON to write.
        logs: The logs, one task each (unlabelled ones too, to label there).
        segments: The labels, as each task's annotation.
        terrains: The terrains, as the config's labels.
        samples: A log's samples ``[start, stop)`` as a ``(stop - start, C)`` array, read a block at a time.
        url_prefix: What goes before a CSV's name in a task (default: Label Studio's local-files URL for the folder,
            ``/data/local-files/?d=NAME-files/``, served with its document root at ``out``'s folder).

    Returns:
        The files written: the tasks file, the config, the CSVs.
    """
    import pandas as pd

    folder = files_folder(out)
    check_new_target(out)
    check_new_target(folder, what="folder")
    folder.mkdir()
    prefix = f"/data/local-files/?d={folder.name}/" if url_prefix is None else url_prefix
    shared = [c for c in logs[0].channel_names if all(c in x.channel_names for x in logs[1:])] if logs else []
    dates = on_dates(logs)
    config = folder / "labeling-config.xml"
    config.write_text(labeling_config(terrains, shared, dates=dates))
    written, tasks = [out, config], []
    for log in logs:
        csv = folder / log_csv_name(log)
        with open(csv, "w", newline="") as f:
            for a in range(0, max(log.n_samples, 1), BLOCK):  # a block at a time: a long log is never held whole
                b = min(a + BLOCK, log.n_samples)
                table = pd.DataFrame(samples(log, a, b), columns=list(log.channel_names))
                # fixed decimals: the channels' 9 significant digits would round an epoch time to 10 s
                times = log.t0 + np.arange(a, b) / log.rate_hz
                table.insert(0, "time", np.char.mod("%.3f" if dates else "%.6f", times))
                table.to_csv(f, index=False, header=a == 0, float_format="%.9g")
        written.append(csv)
        mine = [region(s, log, dates=dates) for s in segments if s.log_id == log.id]
        tasks.append(
            {
                "data": {"csv": prefix + csv.name, "log": log.name, "source_file": log.source_path},
                "annotations": [{"result": mine}] if mine else [],
            }
        )
    with new_file(out) as tmp:
        tmp.write_text(json.dumps(tasks, indent=1))
    return written


def is_label_studio(data: object) -> bool:
    """Whether parsed JSON is a Label Studio export: a list of tasks, each with ``data`` and its annotations."""
    return (
        isinstance(data, list)
        and bool(data)
        and all(
            isinstance(t, dict) and isinstance(t.get("data"), dict) and ("annotations" in t or "completions" in t)
            for t in data
        )
    )


def label_studio_frame(tasks: list[dict], logs: Sequence[LogInfo], *, path: Path) -> pd.DataFrame:
    """The regions of a Label Studio export as label rows: ``log, terrain, start_s, end_s, author`` and ``at``, the
    task and region that messages name.

    Raises:
        LabelError: A task naming no log of the session, a region without a terrain, an instant, times that are no
            numbers or lie outside the log; the message names the task. Nothing is imported then.
    """
    import pandas as pd

    by_name = {x.name: x for x in logs}
    by_file = {log_csv_name(x)[:-4]: x for x in logs}
    rows = []
    for i, task in enumerate(tasks, start=1):
        name = f"task {i}" + (f" (id {task['id']})" if "id" in task else "")
        where = f"{path}: {name}"
        log = _task_log(task["data"], by_name, by_file)
        if log is None:
            raise LabelError(
                f"{where}: names no log of this session (data.log, or a data file named after a log); nothing was "
                "imported"
            )
        annotations = task.get("annotations", task.get("completions")) or []
        if not isinstance(annotations, list):
            raise LabelError(f"{where}: annotations is not a list; nothing was imported")
        for annotation in annotations:
            if not isinstance(annotation, dict) or not isinstance(annotation.get("result", []), list):
                raise LabelError(f"{where}: an annotation without a result list; nothing was imported")
            if annotation.get("was_cancelled"):
                continue
            author = _author(annotation.get("completed_by"))
            for k, result in enumerate(annotation.get("result", []), start=1):
                if not isinstance(result, dict):
                    raise LabelError(f"{where}: a result that is no object ({result!r:.40}); nothing was imported")
                if result.get("type") != "timeserieslabels":
                    continue  # another control of the project (choices, text...): not a terrain span
                start_s, end_s, terrain = _span(result.get("value"), log, where=where)
                rows.append((log.name, terrain, start_s, end_s, author, f"{name}, region {k}"))
    return pd.DataFrame(rows, columns=["log", "terrain", "start_s", "end_s", "author", "at"])


def task_log(data: object, logs: Sequence[LogInfo]) -> LogInfo | None:
    """The log of ``logs`` a Label Studio task's ``data`` names (``data.log``, else a data file named after a log), or
    ``None``."""
    if not isinstance(data, dict):
        return None
    return _task_log(data, {x.name: x for x in logs}, {log_csv_name(x)[:-4]: x for x in logs})


def _task_log(data: dict, by_name: dict[str, LogInfo], by_file: dict[str, LogInfo]) -> LogInfo | None:
    """The log a task's data names: by ``log``, else by a file named after it (a log's name, or its CSV's)."""
    if isinstance(data.get("log"), str) and data["log"] in by_name:
        return by_name[data["log"]]
    for value in data.values():
        if not isinstance(value, str):
            continue
        stem = re.split(r"[/=\\]", value.split("?")[-1] if "?" in value else value)[-1].rsplit(".", 1)[0]
        for candidate in (stem, UPLOAD_PREFIX.sub("", stem)):
            if candidate in by_name:
                return by_name[candidate]
            if candidate in by_file:
                return by_file[candidate]
    return None


def _author(who: object) -> str | None:
    if isinstance(who, dict):
        who = who.get("email") or who.get("id")
    if isinstance(who, str) and who:
        return who
    if isinstance(who, int):
        return f"label-studio user {who}"
    return None


def _span(value: object, log: LogInfo, *, where: str) -> tuple[float, float, str]:
    """A region's ``(start_s, end_s, terrain)``, its times as seconds from the log's start."""
    if not isinstance(value, dict):
        raise LabelError(f"{where}: a region without a value; nothing was imported")
    names = value.get("timeserieslabels")
    if not (isinstance(names, list) and len(names) == 1 and isinstance(names[0], str)):
        raise LabelError(
            f"{where}: a region needs one terrain in timeserieslabels, not {names!r}; nothing was imported"
        )
    if value.get("instant"):
        raise LabelError(
            f"{where}: an instant at {value.get('start')!r} labelled {names[0][:80]!r}: a terrain needs a span; "
            "nothing was imported"
        )
    try:
        a, b = float(value["start"]), float(value["end"])
    except (KeyError, TypeError, ValueError):
        raise LabelError(
            f"{where}: region start/end {value.get('start')!r}/{value.get('end')!r} are no numbers (a project whose "
            "time column is a date exports milliseconds: numbers); nothing was imported"
        ) from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise LabelError(f"{where}: region start/end {a}/{b} are not finite; nothing was imported")
    if b <= a:
        raise LabelError(f"{where}: a region from {a:g} to {b:g} ends before it starts; nothing was imported")
    slack, length = 1.0 / log.rate_hz, log.n_samples / log.rate_hz
    # the log's clock (ours), seconds from its start, milliseconds on its clock (a date time column)
    for start, end in ((a - log.t0, b - log.t0), (a, b), (a / 1e3 - log.t0, b / 1e3 - log.t0)):
        if -slack <= start <= end <= length + slack:
            return max(start, 0.0), min(end, length), names[0]
    raise LabelError(
        f"{where}: region {a:g} to {b:g} lies outside log {log.name!r} (its clock runs {log.t0:.3f} to "
        f"{log.t0 + length:.3f} s; {length:.3f} s long); nothing was imported"
    )
