"""uPlot charts of one window of a log: channel groups, and the tracks (labels, model, suggestions, scores) under
them. Pure functions from arrays to ``(data, series, options)``: the view only assigns them.

uPlot draws every series against one x array and viser sends Float64Arrays, where NaN would not make a gap. So a
band (a label, a prediction) is a series at its row's top where it holds and at its row's bottom elsewhere, filled
down to the bottom; and the cursor is a vertical line made of three points at the cursor's time on a scale whose
range starts just above 0.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from labeling import DRIFT_TRACK_AT_1

from .decimate import Decimated

PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")
Y_AXIS_PX = 74  # the same for every chart, so their plotting areas line up
SURPRISE, UNSURE, SELECTION, SUGGESTED = "#ef6c00", "#6a1b9a", "#1e88e5", "#00897b"
DRIFT = "#ad1457"  # the drift row: time unlike anything labelled (no terrain colour is near it)


@dataclass(frozen=True)
class Group:
    """Channels drawn in one chart."""

    title: str
    channels: tuple[int, ...]
    names: tuple[str, ...]


def channel_groups(names: Sequence[str], *, forces_by: str = "foot") -> list[Group]:
    """Charts for a log's channels: IMU quantities one chart each, foot forces by foot or by axis.

    Names look like ``imu/angular_velocity.x`` or ``fl/force.z`` (MCAP) or free CSV columns; channels are grouped by
    the part before the last ``.`` (or ``_``) and charts keep at most 6 channels.
    """
    groups: dict[str, list[int]] = {}
    for i, name in enumerate(names):
        base, axis = _split(name)
        by_axis = "force" in base.lower() and forces_by == "axis"
        key = f"{re.sub(r'^.*/', '', base)} {axis}".strip() if by_axis else base
        groups.setdefault(key, []).append(i)
    out = []
    for key, idx in groups.items():
        for k in range(0, len(idx), 6):
            part = tuple(idx[k : k + 6])
            title = key.replace("_", " ") + ("" if k == 0 else f" ({k // 6 + 1})")
            out.append(Group(title, part, tuple(_short(names[i], key) for i in part)))
    return out


def _split(name: str) -> tuple[str, str]:
    for sep in (".", "_"):
        if sep in name:
            base, axis = name.rsplit(sep, 1)
            if len(axis) <= 2:
                return base, axis
    return name, ""


def _short(name: str, key: str) -> str:
    base, axis = _split(name)
    if key == base:
        return axis or name
    return base.split("/")[0] if "/" in base else name


def with_cursor(t: np.ndarray, columns: Sequence[np.ndarray], cursor_s: float | None):
    """Insert the cursor time three times into ``t`` (interpolating ``columns``) and build the cursor series.

    Returns:
        ``(t', columns', line)`` where ``line`` is ``(P',)``: 1 at the middle inserted point, 0 elsewhere.
    """
    if cursor_s is None or len(t) == 0 or not (t[0] <= cursor_s <= t[-1]):
        return t, list(columns), np.zeros(len(t))
    i = int(np.searchsorted(t, cursor_s))
    t2 = np.concatenate([t[:i], [cursor_s] * 3, t[i:]])
    cols = [np.concatenate([c[:i], [np.interp(cursor_s, t, c)] * 3, c[i:]]) for c in columns]
    line = np.zeros(len(t2))
    line[i + 1] = 1.0
    return t2, cols, line


def _cursor_series() -> dict:
    return {"label": "cursor", "scale": "cursor", "stroke": "#212121", "width": 1.5, "points": {"show": False}}


def trace_chart(dec: Decimated, group: Group, *, cursor_s: float | None, show_x: bool, height: int = 110) -> dict:
    """A chart of one channel group: ``{"data", "series", "scales", "axes", "height", ...}`` for ``add_uplot``."""
    cols = [dec.values[:, c].astype(np.float64) for c in group.channels]
    t, cols, line = with_cursor(dec.t, cols, cursor_s)
    series = [{"label": "t (s)"}]
    for k, name in enumerate(group.names):
        series.append({"label": name, "stroke": PALETTE[k % len(PALETTE)], "width": 1, "points": {"show": False}})
    series.append(_cursor_series())
    return {
        "data": (t, *cols, line),
        "series": tuple(series),
        "scales": {"x": {"time": False}, "cursor": {"auto": False, "range": (0.01, 1.0)}},
        "axes": (
            {"show": show_x, "size": 28 if show_x else 0},
            {"size": Y_AXIS_PX, "label": group.title, "labelSize": 14, "labelFont": "11px sans-serif"},
        ),
        "legend": {"show": True, "live": False},
        "cursor": {"sync": {"key": "wb-window"}, "drag": {"x": False, "y": False}},
        "height": height,
        "padding": (4, 12, 0, 0),
    }


@dataclass(frozen=True)
class TrackInputs:
    """What the tracks chart shows of a window, each at the decimated times ``t`` (``(P,)``)."""

    t: np.ndarray
    labels: np.ndarray  # (P,) terrain index, -1 unlabelled
    predicted: np.ndarray | None  # (P,) class index into ``terrains`` (-1: not known)
    surprise: np.ndarray | None  # (P,) in [0, 1]
    unsure: np.ndarray | None  # (P,) in [0, 1]
    highlight: np.ndarray | None  # (P,) bool: inside a highlighted interval
    suggested: np.ndarray  # (P,) bool
    current: np.ndarray  # (P,) bool: the suggestion being looked at
    selection: np.ndarray  # (P,) bool
    confidence: np.ndarray | None = None  # (P,) the predicted stretch's mean probability
    review: np.ndarray | None = None  # (P,) bool: the stretch under review
    drift: np.ndarray | None = None  # (P,) drift track in [0, 1): DRIFT_TRACK_AT_1 and up: unlike anything labelled


# The model's stretches are drawn more opaque the surer it is: below 0.6, 0.6 to 0.8, above 0.8 (hex alpha).
CONFIDENCE_LEVELS = ((0.0, "38"), (0.6, "80"), (0.8, "e6"))
ROWS = {"labels": (5.1, 5.9), "model": (4.1, 4.9), "suggested": (3.1, 3.9), "drift": (2.1, 2.9), "scores": (0.0, 1.9)}


def _band(mask: np.ndarray, row: str) -> np.ndarray:
    lo, hi = ROWS[row]
    return np.where(mask, hi, lo).astype(np.float64)


def tracks_chart(
    x: TrackInputs, terrains: Sequence[tuple[str, str]], *, cursor_s: float | None, height: int = 150
) -> dict:
    """Labels and the model's guess coloured by terrain, suggestions, time unlike anything labelled (drift), the
    selection, surprise and uncertainty with their highlighted intervals: one chart so they share the window and the
    cursor."""
    cols: list[np.ndarray] = []
    series: list[dict] = [{"label": "t (s)"}]

    def add(values: np.ndarray, label: str, fill: str, *, fill_to: float, stroke: str | None = None) -> None:
        cols.append(values)
        series.append(
            {
                "label": label,
                "scale": "rows",
                "fill": fill,
                "fillTo": fill_to,
                "width": 0 if stroke is None else 1.2,
                "stroke": stroke or "rgba(0,0,0,0)",
                "points": {"show": False},
            }
        )

    add(np.where(x.selection, 6.0, 0.0), "selection", SELECTION + "26", fill_to=0.0)
    for k, (name, color) in enumerate(terrains):
        add(_band(x.labels == k, "labels"), f"label {name}", color, fill_to=ROWS["labels"][0])
    if x.predicted is not None:
        conf = x.confidence if x.confidence is not None else np.ones(len(x.predicted))
        bounds = [lo for lo, _ in CONFIDENCE_LEVELS[1:]] + [np.inf]
        for k, (name, color) in enumerate(terrains):
            for (lo, alpha), hi in zip(CONFIDENCE_LEVELS, bounds, strict=True):
                level = (x.predicted == k) & (conf >= lo) & (conf < hi)
                add(_band(level, "model"), f"model {name} ≥{lo:g}", color + alpha, fill_to=ROWS["model"][0])
        # the stretch under review: a dark bar along the top of the model row (always a series: a new series list
        # rebuilds the chart)
        review = x.review if x.review is not None else np.zeros(len(x.predicted), bool)
        bar = ROWS["model"][1] + 0.05
        add(np.where(review, bar + 0.15, bar), "stretch under review", "#212121", fill_to=bar)
    add(_band(x.suggested, "suggested"), "suggested", SUGGESTED + "66", fill_to=ROWS["suggested"][0])
    add(_band(x.current, "suggested"), "current suggestion", SUGGESTED, fill_to=ROWS["suggested"][0])
    if x.drift is not None:
        lo, hi = ROWS["drift"]
        add(_band(x.drift >= DRIFT_TRACK_AT_1, "drift"), "unlike anything labelled", DRIFT + "99", fill_to=lo)
        add(lo + (hi - lo) * x.drift, "drift", "rgba(0,0,0,0)", fill_to=lo, stroke=DRIFT)
    top = ROWS["scores"][1]
    if x.highlight is not None:
        add(np.where(x.highlight, top, 0.0), "highlight", "#ffb30040", fill_to=0.0)
    if x.surprise is not None:
        add(top * x.surprise, "surprise", "rgba(0,0,0,0)", fill_to=0.0, stroke=SURPRISE)
    if x.unsure is not None:
        add(top * x.unsure, "uncertainty", "rgba(0,0,0,0)", fill_to=0.0, stroke=UNSURE)
    t, cols, line = with_cursor(x.t, cols, cursor_s)
    return {
        "data": (t, *cols, line),
        "series": (*series, _cursor_series()),
        "scales": {
            "x": {"time": False},
            "rows": {"auto": False, "range": (0.0, 6.0)},
            "cursor": {"auto": False, "range": (0.01, 1.0)},
        },
        "axes": (
            {"show": False, "size": 0},
            {
                "scale": "rows",
                "size": Y_AXIS_PX,
                "label": "",
                "labelSize": 14,
                "splits": (0.95, 2.5, 3.5, 4.5, 5.5),
                "values": ("scores", "drift", "suggested", "model", "labels"),
                "grid": {"show": False},
                "ticks": {"show": False},
                "font": "11px sans-serif",
            },
        ),
        "legend": {"show": False},
        "cursor": {"sync": {"key": "wb-window"}, "drag": {"x": False, "y": False}},
        "height": height,
        "padding": (4, 12, 0, 0),
    }


def per_sample_labels(n: int, segments: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """``(n,)`` terrain index of each sample of a log from ``(start, stop, terrain index)`` segments (-1: none)."""
    out = np.full(n, -1, np.int16)
    for a, b, k in segments:
        out[max(a, 0) : max(b, 0)] = k
    return out
