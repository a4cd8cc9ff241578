"""The far runs of ``evaluate loop``: runs of the same robot kept out of the session entirely, scored after every
round by the bundle the session would export, as ``workbench classify`` scores them (the bundle alone: no labels,
no votes of a run's own labels). The robot gets the bundle, not the session: this is the figure of what ships.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from sessions import IngestOptions, WorkbenchError, read_frame
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
) -> FarRuns:
    """Read the far runs as ``classify`` reads log files, their truth from ``reference`` (a label file naming them).

    Args:
        files: The far runs' log files.
        reference: A label file naming them (columns log, terrain, start_s, end_s).
        bundle: The bundle whose channels and rate the runs are read in.
        session_logs: The session's log names (a far run is none of them).
        options: How the files are read, as ``ingest`` and ``classify`` take them (``--mapping``, ``--rate``,
            ``--allow-gaps``); camera frames are never decoded. Default: ``ingest``'s defaults.

    Raises:
        WorkbenchError: A file is refused, a run is in the session, or a run has no row in the reference.
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
        for start, end, terrain in zip(rows["start_s"], rows["end_s"], rows["terrain"], strict=True):
            lo, hi = (max(0, round(float(x) * bundle.rate_hz)) for x in (start, end))
            y[lo:hi] = terrains.index(str(terrain))
        truth.append(y)
    return FarRuns(read.names, read.arrays, tuple(truth), terrains)


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
