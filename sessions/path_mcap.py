"""A log's path coloured by terrain as Foxglove draws it, in a terrain MCAP file beside the prediction topics.

``/terrain/path`` (``foxglove.SceneUpdate``): one entity per log in the track's frame, a line strip per stretch of
one terrain in its colour (the 3D panel). With GNSS, ``/terrain/geojson`` (``foxglove.GeoJSON``: a FeatureCollection,
one LineString per stretch whose ``properties.style`` colour and weight the Map panel applies) and
``/terrain/fix`` (``foxglove.LocationFix`` per pose, in its stretch's colour). The schemas written are the fields
these messages use; ``tests/sessions/foxglove/`` holds Foxglove's published ones, which every message is checked
against.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

PATH_TOPIC = "/terrain/path"
GEOJSON_TOPIC = "/terrain/geojson"
FIX_TOPIC = "/terrain/fix"
THICKNESS_M = 0.15  # a line a robot's width reads at field scale
MOST_FIXES = 2000  # LocationFix messages of one log (every n-th pose past it)
IDENTITY = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}

_TIME = {"type": "object", "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}}
_XYZ = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_RGBA = {"type": "object", "properties": {k: {"type": "number"} for k in "rgba"}}
SCENE_SCHEMA = {
    "title": "foxglove.SceneUpdate",
    "type": "object",
    "properties": {
        "deletions": {"type": "array"},
        "entities": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "timestamp": _TIME,
                    "frame_id": {"type": "string"},
                    "id": {"type": "string"},
                    "lifetime": _TIME,
                    "frame_locked": {"type": "boolean"},
                    "metadata": {"type": "array"},
                    "lines": {
                        "type": "array",
                        "items": {
                            "type": "object",
                            "properties": {
                                "type": {"type": "integer"},
                                "pose": {"type": "object"},
                                "thickness": {"type": "number"},
                                "scale_invariant": {"type": "boolean"},
                                "points": {"type": "array", "items": _XYZ},
                                "color": _RGBA,
                                "colors": {"type": "array"},
                                "indices": {"type": "array"},
                            },
                        },
                    },
                },
            },
        },
    },
}
GEOJSON_SCHEMA = {"title": "foxglove.GeoJSON", "type": "object", "properties": {"geojson": {"type": "string"}}}
FIX_SCHEMA = {
    "title": "foxglove.LocationFix",
    "type": "object",
    "properties": {
        "timestamp": _TIME,
        "frame_id": {"type": "string"},
        "latitude": {"type": "number"},
        "longitude": {"type": "number"},
        "altitude": {"type": "number"},
        "position_covariance": {"type": "array", "items": {"type": "number"}},
        "position_covariance_type": {"type": "integer"},
        "color": _RGBA,
    },
}


@dataclass(frozen=True)
class TerrainPath:
    """A log's path as drawn, for its terrain MCAP file.

    Attributes:
        frame: The frame of ``xyz`` (a GNSS track's: ``"wgs84"``, ``xyz`` then east and north metres).
        times: ``(N,)`` seconds from the log's first sample.
        xyz: ``(N, 3)`` metres.
        stretches: ``(first pose, last pose + 1, terrain name, "#rrggbb", alpha)`` each.
        geo: ``(N, 3)`` latitude, longitude and altitude of a GNSS track, else ``None``.
    """

    frame: str
    times: np.ndarray
    xyz: np.ndarray
    stretches: tuple[tuple[int, int, str, str, float], ...]
    geo: np.ndarray | None = None


def _rgba(colour: str, alpha: float) -> dict[str, float]:
    c = colour.lstrip("#")
    r, g, b = (int(c[i : i + 2], 16) / 255.0 for i in (0, 2, 4))
    return {"r": r, "g": g, "b": b, "a": float(alpha)}


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": int(ns // 1_000_000_000), "nsec": int(ns % 1_000_000_000)}


def write_path(writer, channel_of, name: str, path: TerrainPath, ns_of) -> None:
    """The path's messages into an open MCAP ``writer``: ``channel_of(topic, schema)`` registers a JSON channel,
    ``ns_of(seconds)`` turns seconds from the log's start into the log's clock in ns."""
    if len(path.times) < 2:
        return
    first = int(ns_of(np.asarray([path.times[0]]))[0])
    lines = [
        {
            "type": 0,  # LINE_STRIP
            "pose": {
                "position": {"x": 0.0, "y": 0.0, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            },
            "thickness": THICKNESS_M,
            "scale_invariant": False,
            "points": [{"x": float(x), "y": float(y), "z": float(z)} for x, y, z in path.xyz[a:b]],
            "color": _rgba(colour, alpha),
            "colors": [],
            "indices": [],
        }
        for a, b, _, colour, alpha in path.stretches
        if b - a >= 2
    ]
    entity = {
        "timestamp": _stamp(first),
        "frame_id": path.frame,
        "id": f"path/{name}",
        "lifetime": {"sec": 0, "nsec": 0},  # kept until the end
        "frame_locked": False,
        "metadata": [{"key": "log", "value": name}],
        "arrows": [],
        "cubes": [],
        "spheres": [],
        "cylinders": [],
        "lines": lines,
        "triangles": [],
        "texts": [],
        "models": [],
    }
    scene = channel_of(PATH_TOPIC, SCENE_SCHEMA)
    writer.add_message(
        scene, log_time=first, publish_time=first, data=json.dumps({"deletions": [], "entities": [entity]}).encode()
    )
    if path.geo is None:
        return
    features = [
        {
            "type": "Feature",
            "geometry": {
                "type": "LineString",
                "coordinates": [[float(lon), float(lat)] for lat, lon, _ in path.geo[a:b]],
            },
            "properties": {"name": terrain, "log": name, "style": {"color": colour, "weight": 4, "opacity": alpha}},
        }
        for a, b, terrain, colour, alpha in path.stretches
        if b - a >= 2
    ]
    geojson = json.dumps({"type": "FeatureCollection", "features": features})
    geo = channel_of(GEOJSON_TOPIC, GEOJSON_SCHEMA)
    writer.add_message(geo, log_time=first, publish_time=first, data=json.dumps({"geojson": geojson}).encode())
    _write_fixes(writer, channel_of(FIX_TOPIC, FIX_SCHEMA), path, ns_of)


def _write_fixes(writer, channel: int, path: TerrainPath, ns_of) -> None:
    colour_at: list[dict[str, float]] = [{"r": 0.62, "g": 0.62, "b": 0.62, "a": 0.7}] * len(path.times)
    for a, b, _, colour, alpha in path.stretches:
        colour_at[a:b] = [_rgba(colour, alpha)] * (b - a)
    step = max(1, -(-len(path.times) // MOST_FIXES))
    at = np.arange(0, len(path.times), step)
    stamps = ns_of(path.times[at])
    for i, ns in zip(at, stamps, strict=True):
        lat, lon, alt = (float(v) for v in path.geo[i])  # type: ignore[index]
        fix = {
            "timestamp": _stamp(int(ns)),
            "frame_id": "gnss",
            "latitude": lat,
            "longitude": lon,
            "altitude": alt,
            "position_covariance": [0.0] * 9,
            "position_covariance_type": 0,  # UNKNOWN
            "color": colour_at[int(i)],
        }
        writer.add_message(channel, log_time=int(ns), publish_time=int(ns), data=json.dumps(fix).encode())


def path_topics(path: TerrainPath | None) -> Sequence[str]:
    """The topics a path adds to its file."""
    if path is None or len(path.times) < 2:
        return ()
    return (PATH_TOPIC,) if path.geo is None else (PATH_TOPIC, GEOJSON_TOPIC, FIX_TOPIC)
