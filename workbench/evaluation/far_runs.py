"""The far runs of ``evaluate loop``: runs of the same robot kept out of the session entirely, scored after every
round by the bundle the session would export, as ``workbench classify`` scores them (the bundle alone: no labels,
no votes of a run's own labels). The robot gets the bundle, not the session: this is the figure of what ships.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sessions import IngestOptions, Session, WorkbenchError, read_frame
from training import ModelBundle

from ..export import read_logs, score_arrays


@dataclass(frozen=True)
class FarRuns:
    """Runs kept out of the session and their truth.

    Attributes:
        names: Each run's name (as ``classify`` names it).
        arrays: Each run's ``(T, C)`` samples in the bundle's channel order, at its rate.
        truth: Each run's ``(T,)`` index into ``terrains`` per sample (``-1``: no truth there).
        terrains: The terrains the truth names.
    """

    names: tuple[str, ...]
    arrays: tuple[np.ndarray, ...]
    truth: tuple[np.ndarray, ...]
    terrains: tuple[str, ...]


@dataclass(frozen=True)
class FarScore:
    """A bundle on the far runs: accuracy over every step with truth, balanced accuracy, and accuracy per run."""

    accuracy: float
    balanced: float
    per_log: dict[str, float]


def read_far_runs(
    files: Sequence[Path],
    reference: Path,
    bundle: ModelBundle,
    *,
    session_logs: Sequence[str],
    options: IngestOptions | None = None,
    recorded: Mapping[Path, Sequence[str]] | None = None,
    terrains_known: Sequence[str] | None = None,
) -> FarRuns:
    """Read the far runs as ``classify`` reads log files, their truth from ``reference`` (a label file naming them).

    Args:
        files: The far runs' log files.
        reference: A label file naming them (columns log, terrain, start_s, end_s).
        bundle: The bundle whose channels and rate the runs are read in.
        session_logs: The session's log names (a far run is none of them).
        options: How the files are read, as ``ingest`` and ``classify`` take them (``--mapping``, ``--rate``,
            ``--allow-gaps``); camera frames are never decoded. Default: ``ingest``'s defaults.
        recorded: Far files whose content is a recording the session holds (``Session.logs_recorded_in``): such a
            file is a log of the session under another name, never a far run.
        terrains_known: The session's terrains: a truth row naming another (or none) is refused, as the session's
            own reference is.

    Raises:
        WorkbenchError: A file is refused, a run is in the session (by name or by content), a run has no row in
            the reference, or a row of it is malformed (a blank or unknown terrain, times that are not finite,
            not increasing or outside the run), each in one line naming the file and the row.
    """
    read = read_logs(bundle, files, replace(options or IngestOptions(), camera_fps=0))
    if read.errors:
        raise WorkbenchError(f"--far: {read.errors[0]}")
    if not read.names:
        raise WorkbenchError("--far: no run read from the files given")
    inside = sorted(set(read.names) & set(session_logs))
    if inside:
        raise WorkbenchError(
            f"--far: {inside[0]} is a log of the session; a far run is one the session never saw (leave it out of "
            "the session, or out of --far)"
        )
    for path, names in (recorded or {}).items():  # by content: a copy of a session log under another name
        raise WorkbenchError(
            f"--far: {path} holds the recording of the session's log {names[0]} (the same content under another "
            "name); a far run is one the session never saw"
        )
    frame = read_frame(Path(reference))
    if not {"log", "terrain", "start_s", "end_s"} <= set(frame.columns):
        raise WorkbenchError(f"{reference}: the far runs' truth needs columns log, terrain, start_s and end_s")
    stray = sorted(set(frame["log"].astype(str)) - set(read.names) - set(session_logs))
    if stray:
        raise WorkbenchError(f"{reference}: log {stray[0]!r} is neither a log of the session nor a far run")
    terrains = tuple(sorted({str(t) for t, n in zip(frame["terrain"], frame["log"], strict=True) if n in read.names}))
    truth = []
    for name, a in zip(read.names, read.arrays, strict=True):
        rows = frame[frame["log"].astype(str) == name]
        if rows.empty:
            raise WorkbenchError(f"{reference}: no row names the far run {name}; give its truth there")
        y = np.full(len(a), -1, np.int64)
        for index, start, end, terrain in zip(rows.index, rows["start_s"], rows["end_s"], rows["terrain"], strict=True):
            where = f"{reference}: row {int(index) + 2}"
            lo, hi = _span(start, end, len(a) / bundle.rate_hz, where=where)
            _known(terrain, terrains_known, where=where)
            y[round(lo * bundle.rate_hz) : round(hi * bundle.rate_hz)] = terrains.index(str(terrain))
        truth.append(y)
    return FarRuns(read.names, read.arrays, tuple(truth), terrains)


def far_runs_of(
    session: Session, files: Sequence[Path], reference: Path, bundle: ModelBundle, *, options: IngestOptions | None
) -> FarRuns:
    """:func:`read_far_runs` against ``session``: none of its logs by name or by content, its terrains only."""
    return read_far_runs(
        files,
        reference,
        bundle,
        session_logs=[x.name for x in session.logs()],
        options=options,
        recorded={p: [x.name for x in logs] for p, logs in session.logs_recorded_in(files).items()},
        terrains_known=[t.name for t in session.terrains()],
    )


def _span(start: object, end: object, duration_s: float, *, where: str) -> tuple[float, float]:
    """A truth row's ``(start_s, end_s)``, clipped to the run, or a ``WorkbenchError`` naming the row."""
    if any(_blank(x) for x in (start, end)):
        raise WorkbenchError(f"{where}: start_s and end_s must be given, in seconds from the run's start")
    try:
        lo, hi = float(start), float(end)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise WorkbenchError(f"{where}: start_s {start} and end_s {end} must be numbers of seconds") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or not 0 <= lo < hi:
        raise WorkbenchError(f"{where}: start_s {lo:g} and end_s {hi:g} must be finite, from 0 and increasing")
    if lo >= duration_s:
        raise WorkbenchError(f"{where}: starts at {lo:g} s, after the run's end ({duration_s:.1f} s)")
    return lo, min(hi, duration_s)


def _blank(value: object) -> bool:
    """A cell holding nothing: CSV cells are read as text (empty: ""), Parquet and JSON ones may be null."""
    return value is None or (isinstance(value, float) and math.isnan(value)) or not str(value).strip()


def _known(terrain: object, known: Sequence[str] | None, *, where: str) -> None:
    """Refuse a truth row whose terrain is blank, or not a terrain of the session."""
    if _blank(terrain):
        raise WorkbenchError(f"{where}: terrain is empty; every row of a far run's truth names its terrain")
    if known is not None and str(terrain) not in known:
        raise WorkbenchError(
            f"{where}: unknown terrain {str(terrain)!r}; the far runs' truth names terrains of the session "
            f"({', '.join(known)})"
        )


def score_far(bundle: ModelBundle, far: FarRuns) -> FarScore:
    """What ``bundle`` scores on the far runs, by the bundle alone (``classify``'s path)."""
    scored = score_arrays(bundle, far.arrays)
    # the bundle's class -> the truth's terrain (a class the truth never names is never right: -2)
    index = np.array([far.terrains.index(c) if c in far.terrains else -2 for c in bundle.classes])
    true_all, pred_all, per_log = [], [], {}
    for name, t, s in zip(far.names, far.truth, scored, strict=True):
        keep = t >= 0
        p = index[np.asarray(s.probs).argmax(axis=1)][keep]
        if keep.any():
            per_log[name] = float((p == t[keep]).mean())
            true_all.append(t[keep])
            pred_all.append(p)
    t, p = np.concatenate(true_all), np.concatenate(pred_all)
    recalls = [float((p[t == c] == c).mean()) for c in np.unique(t)]
    return FarScore(float((t == p).mean()), float(np.mean(recalls)), per_log)
