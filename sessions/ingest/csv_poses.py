"""A CSV's position columns: ``x, y[, z]`` or ``lat, lon[, alt]``, read as a pose track and not as signals.

``x, y, z`` is also what a phone's sensor logger calls an accelerometer's axes, so a pair is a position only when it
moves like one: smoothly, each step a small part of the ground covered (a signal's steps are as large as its
range). A pair of latitude and longitude columns is a position whatever it does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .poses import ALTITUDE_NAMES, LATITUDE_NAMES, LONGITUDE_NAMES, PoseTrack, clean

if TYPE_CHECKING:
    import pandas as pd

SMOOTH = 0.02  # a position's median step is under this share of the ground it covers (noise: about a third)


def pose_columns(frame: pd.DataFrame, columns: list) -> tuple[str, list] | None:
    """The kind (``"gnss"`` or ``"csv"``) and the columns of a CSV's position, or ``None``."""
    by_name = {str(c).strip().lower(): c for c in columns}
    lat = next((by_name[n] for n in LATITUDE_NAMES if n in by_name), None)
    lon = next((by_name[n] for n in LONGITUDE_NAMES if n in by_name), None)
    if lat is not None and lon is not None:
        alt = next((by_name[n] for n in ALTITUDE_NAMES if n in by_name), None)
        return "gnss", [lat, lon] + ([alt] if alt is not None else [])
    xy = [by_name.get(n) for n in ("x", "y")]
    if None in xy or not all(_moves_like_a_position(frame[c]) for c in xy):
        return None
    return "csv", xy + ([by_name["z"]] if "z" in by_name else [])


def _numbers(column: pd.Series) -> np.ndarray:
    import pandas as pd

    return np.asarray(pd.to_numeric(column, errors="coerce"), np.float64)  # text cells: NaN, dropped as poses


def _moves_like_a_position(column: pd.Series) -> bool:
    v = _numbers(column)
    if len(v) < 10 or not np.isfinite(v).any():
        return False
    v = v[np.isfinite(v)]
    spread = float(np.percentile(v, 95) - np.percentile(v, 5))
    if spread <= 0:
        return False
    return float(np.median(np.abs(np.diff(v)))) < SMOOTH * spread


def csv_track(frame: pd.DataFrame, times: np.ndarray, found: tuple[str, list], *, source: str) -> tuple[PoseTrack, str]:
    """The pose track of the columns :func:`pose_columns` found, cleaned, and the note that says so."""
    kind, cols = found
    values = np.full((len(frame), 3), 0.0)
    for j, c in enumerate(cols):
        values[:, j] = _numbers(frame[c])
    frame_name = "wgs84" if kind == "gnss" else "csv"  # a CSV's x, y: its own run's frame
    track = clean(PoseTrack(kind, f"{source}:{','.join(map(str, cols))}", frame_name, np.asarray(times), values))
    note = f"columns {', '.join(map(str, cols))} read as the robot's position (a pose track), not as signals"
    if track.dropped:
        note += (
            f"; {track.dropped:,} of {len(frame):,} positions dropped as impossible (not finite, out of range or a "
            "jump)"
        )
    return track, note
