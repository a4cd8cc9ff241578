"""Where a demo walk goes: a field whose patches are the terrains, the same field for every walk.

The field is a disc cut into one sector per terrain (``TERRAINS``' order), meeting at its centre. A walk's terrain
changes only at the centre: each stretch of one terrain is a petal inside that terrain's sector, out from the centre
and back, as long as the ground the walk covers then (``Walk.distance``), so the terrain under the robot is the one
its signals and its camera show at every moment, and a patch crossed by two walks lines up on the map.
"""

from __future__ import annotations

import numpy as np

from .walks import TERRAINS, Walk

FIELD_LAT, FIELD_LON = 45.3786, -71.9236  # a field near Sherbrooke, Quebec: where the GNSS fixes are
EARTH_RADIUS_M = 6_371_008.8
LONGEST_PETAL_M = 30.0  # a stretch longer than two of these walks several petals


def field_positions(walk: Walk) -> np.ndarray:
    """``(T, 2)`` east and north metres from the field's centre at each of the walk's samples."""
    out = np.zeros((len(walk.times), 2))
    width = 2 * np.pi / len(TERRAINS)
    for a, b, terrain in walk.truth:
        inside = (walk.times >= a) & (walk.times < b)
        if not inside.any():
            continue
        s = walk.distance[inside] - walk.distance[inside][0]  # (n,) metres into the stretch
        length = max(float(s[-1]), 1e-6)
        mid = (TERRAINS.index(terrain) + 0.5) * width
        out[inside] = _petals(s, length, mid - width / 3, mid + width / 3)
    return out


def _petals(s: np.ndarray, length: float, left: float, right: float) -> np.ndarray:
    """Points at arc lengths ``s`` along petals (centre → out at ``left`` → across → back at ``right``) that
    together are ``length`` long."""
    n = max(1, int(np.ceil(length / (2 * LONGEST_PETAL_M))))
    chord = 2 * np.sin((right - left) / 2)  # the crossing's length per metre of radius
    r = length / n / (2 + chord)
    one = r * (2 + chord)
    u = np.mod(s, one) / r  # (n,) in radii along one petal: out [0, 1), across [1, 1 + chord), back
    out_dir = np.array([np.cos(left), np.sin(left)])
    back_dir = np.array([np.cos(right), np.sin(right)])
    going = np.clip(u, 0, 1)[:, None] * out_dir
    across = out_dir + np.clip((u - 1) / chord, 0, 1)[:, None] * (back_dir - out_dir)
    coming = np.clip(2 + chord - u, 0, 1)[:, None] * back_dir
    pts = np.where((u < 1)[:, None], going, np.where((u < 1 + chord)[:, None], across, coming))
    return r * pts


def to_fix(east_north: np.ndarray) -> np.ndarray:
    """Latitude and longitude (degrees) of east and north metres from the field's centre."""
    lat = FIELD_LAT + np.degrees(east_north[:, 1] / EARTH_RADIUS_M)
    lon = FIELD_LON + np.degrees(east_north[:, 0] / (EARTH_RADIUS_M * np.cos(np.radians(FIELD_LAT))))
    return np.column_stack([lat, lon])
