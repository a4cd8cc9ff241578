"""Where the robot was: a log's pose track, found as the IMU is found (by message type and by field names).

A track is kept beside a log's signals, never among them: a model that learned the robot's position would name
the terrain by where it was recorded, which a new run does not share. Positions come from an odometry or pose
topic (metres in that topic's frame), from ``/tf`` (a child frame's translation), from a GNSS fix (latitude and
longitude, drawn in local metres from the first fix), or from a CSV's ``x, y[, z]`` or ``lat, lon`` columns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .fields import get, keys

EARTH_RADIUS_M = 6_371_008.8  # the mean radius: local metres from a fix are within 0.5 % over a field's size
FASTEST_M_S = 100.0  # a pose further from the one before than this speed allows is a jump, not the robot
GNSS_KINDS = ("gnss",)

# message type -> the path of the position in it, and the kind of track it gives
POSE_PATHS: dict[str, tuple[tuple[str, ...], str]] = {
    "nav_msgs/Odometry": (("pose", "pose", "position"), "odometry"),
    "geometry_msgs/PoseWithCovarianceStamped": (("pose", "pose", "position"), "pose"),
    "geometry_msgs/PoseStamped": (("pose", "position"), "pose"),
    "geometry_msgs/PointStamped": (("point",), "pose"),
}
LATITUDE_NAMES = ("latitude", "lat")
LONGITUDE_NAMES = ("longitude", "lon", "lng", "long")
ALTITUDE_NAMES = ("altitude", "alt", "height")
BASE_FRAMES = ("base_link", "base_footprint", "base", "body", "trunk")  # /tf's child frame when none is named


@dataclass(frozen=True)
class PoseTrack:
    """A log's positions on the log's clock.

    Attributes:
        kind: ``"odometry"``, ``"pose"``, ``"tf"``, ``"gnss"``, ``"csv"`` or ``"dead-reckoned"``.
        source: Where it was read (``"topic"``, ``"topic:child frame"``, ``"file:x,y"``).
        frame: The frame its positions are in (a GNSS track: ``"wgs84"``); tracks of one frame line up.
        times: ``(N,)`` float64 seconds, increasing, on the clock of the log's streams.
        values: ``(N, 3)`` float64: x, y, z in metres, or latitude, longitude (degrees) and altitude (metres).
        dropped: Poses left out as impossible (not finite, time going back, a jump, a latitude past 90°).
    """

    kind: str
    source: str
    frame: str
    times: np.ndarray
    values: np.ndarray
    dropped: int = 0

    @property
    def geographic(self) -> bool:
        """Whether ``values`` are latitude, longitude and altitude."""
        return self.kind in GNSS_KINDS


def position_of(schema: str, message: object) -> tuple[float, float, float] | None:
    """The position a message of a pose type carries, else ``None``."""
    found = POSE_PATHS.get(schema.replace("/msg/", "/"))
    if found is None:
        return None
    point = get(message, found[0])
    return float(get(point, ("x",))), float(get(point, ("y",))), float(get(point, ("z",)))


def gnss_fields(message: object) -> tuple[str, str, str | None] | None:
    """The names of a message's latitude, longitude and (if any) altitude fields, at its top level: a GNSS driver's
    own message as much as ``sensor_msgs/NavSatFix``; ``None`` when it has no latitude and longitude."""
    names = {k.lower(): k for k in keys(message)}
    lat = next((names[n] for n in LATITUDE_NAMES if n in names), None)
    lon = next((names[n] for n in LONGITUDE_NAMES if n in names), None)
    alt = next((names[n] for n in ALTITUDE_NAMES if n in names), None)
    return None if lat is None or lon is None else (lat, lon, alt)


def fix_of(message: object, found: tuple[str, str, str | None]) -> tuple[float, float, float]:
    """Latitude, longitude and altitude (0 where the message has none) by the names :func:`gnss_fields` found."""
    lat, lon, alt = found
    return (
        float(get(message, (lat,))),
        float(get(message, (lon,))),
        float(get(message, (alt,))) if alt is not None else 0.0,
    )


def tf_translations(
    message: object, child: str | None
) -> list[tuple[str, str, tuple[float, float, float], float | None]]:
    """Each transform of a ``tf2_msgs/TFMessage`` as (parent frame, child frame, translation, its stamp in seconds
    or ``None``), of ``child`` only when it is given."""
    from .fields import stamp_seconds

    out = []
    for t in get(message, ("transforms",)):
        name = str(get(t, ("child_frame_id",))).lstrip("/")
        if child is not None and name != child.lstrip("/"):
            continue
        parent = str(get(t, ("header", "frame_id"))).lstrip("/")
        v = get(t, ("transform", "translation"))
        xyz = (float(get(v, ("x",))), float(get(v, ("y",))), float(get(v, ("z",))))
        out.append((parent, name, xyz, stamp_seconds(t, ())))
    return out


def base_frame(children: set[str]) -> str | None:
    """The child frame of ``/tf`` a track follows when the mapping names none: the robot's base."""
    return next((f for f in BASE_FRAMES if f in children), None)


def clean(track: PoseTrack) -> PoseTrack:
    """``track`` without the poses that cannot be the robot's: not finite, latitude past ±90° or longitude past
    ±180°, at or before the time of the pose before it, or further from its kept neighbour than
    :data:`FASTEST_M_S` allows in the time between (a jump of 1,000 km in one step); ``dropped`` counts them.

    The walk starts from the pose nearest the track's median position, forward and back, so that one wild pose at
    the start cannot make the whole track look like a jump."""
    times, values = np.asarray(track.times, np.float64), np.asarray(track.values, np.float64)
    ok = np.isfinite(times) & np.isfinite(values).all(axis=1)
    if track.geographic:
        ok &= (np.abs(values[:, 0]) <= 90.0) & (np.abs(values[:, 1]) <= 180.0)
    idx = np.flatnonzero(ok)
    keep = np.zeros(len(times), bool)
    if len(idx):
        centre = np.median(values[idx], axis=0)
        seed = int(idx[np.argmin(np.abs(values[idx] - centre).sum(axis=1))])
        keep[seed] = True
        for step in (1, -1):  # forward from the seed, then back from it
            last = seed
            for i in idx[idx > seed] if step == 1 else idx[idx < seed][::-1]:
                dt = (times[i] - times[last]) * step
                if dt <= 0 or _distance(values[last], values[i], track.geographic) > FASTEST_M_S * dt + 1.0:
                    continue
                keep[i] = True
                last = i
    return PoseTrack(
        track.kind,
        track.source,
        track.frame,
        times[keep],
        values[keep],
        track.dropped + int(len(times) - keep.sum()),
    )


def _distance(a: np.ndarray, b: np.ndarray, geographic: bool) -> float:
    """Metres between two poses (great-circle for fixes, by the haversine)."""
    if not geographic:
        return float(np.linalg.norm(b - a))
    la1, lo1, la2, lo2 = (math.radians(float(x)) for x in (a[0], a[1], b[0], b[1]))
    h = math.sin((la2 - la1) / 2) ** 2 + math.cos(la1) * math.cos(la2) * math.sin((lo2 - lo1) / 2) ** 2
    return 2 * EARTH_RADIUS_M * math.asin(min(1.0, math.sqrt(h)))


def local_metres(values: np.ndarray, origin: tuple[float, float]) -> np.ndarray:
    """Latitude and longitude (``(N, >=2)`` degrees) as east and north metres from ``origin`` (an equirectangular
    view about it: within a fraction of a percent over the few kilometres a robot drives)."""
    lat0, lon0 = (math.radians(x) for x in origin)
    lat, lon = np.radians(values[:, 0]), np.radians(values[:, 1])
    east = EARTH_RADIUS_M * math.cos(lat0) * (lon - lon0)  # (N,)
    north = EARTH_RADIUS_M * (lat - lat0)  # (N,)
    return np.stack([east, north], axis=1)  # (N, 2)
