"""A log's path coloured by terrain in its terrain MCAP file: every message valid against Foxglove's published
schemas (``foxglove/``), a line strip per stretch in its colour, GNSS as GeoJSON and LocationFix for the Map panel."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
from mcap.reader import make_reader

from sessions import LogClock, TerrainPath
from sessions.terrain_mcap import write_terrain_mcap

PUBLISHED = {
    "/terrain/path": "SceneUpdate.json",
    "/terrain/geojson": "GeoJSON.json",
    "/terrain/fix": "LocationFix.json",
}


def _messages(path: Path) -> dict[str, list[dict]]:
    out: dict[str, list[dict]] = {}
    checks = {
        topic: jsonschema.Draft7Validator(json.loads((Path(__file__).parent / "foxglove" / name).read_text()))
        for topic, name in PUBLISHED.items()
    }
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            data = json.loads(message.data)
            if channel.topic in checks:
                assert schema.name == "foxglove." + PUBLISHED[channel.topic].removesuffix(".json")
                checks[channel.topic].validate(data)  # Foxglove's own schema, not the one we wrote
            out.setdefault(channel.topic, []).append(data)
    return out


def _path(geo: bool) -> TerrainPath:
    t = np.arange(100) / 10.0  # 10 s at 10 Hz
    xyz = np.column_stack([t, np.zeros(100), np.zeros(100)])
    runs = ((0, 41, "grass", "#4caf50", 1.0), (40, 71, "gravel", "#795548", 0.45), (70, 100, "unsure", "#cfcfcf", 0.7))
    lla = np.column_stack([45.38 + t * 1e-6, np.full(100, -71.92), np.full(100, 250.0)]) if geo else None
    return TerrainPath("wgs84" if geo else "odom", t, xyz, runs, lla)


def test_the_path_is_one_line_strip_per_stretch_in_its_colour(tmp_path: Path) -> None:
    out = write_terrain_mcap(tmp_path / "w.mcap", LogClock("w", 1000.0, 100.0, 1000), path_drawn=_path(geo=False))
    msgs = _messages(out)
    assert set(msgs) == {"/terrain/path"}
    (update,) = msgs["/terrain/path"]
    (entity,) = update["entities"]
    assert entity["frame_id"] == "odom" and entity["id"] == "path/w" and entity["timestamp"] == {"sec": 1000, "nsec": 0}
    lines = entity["lines"]
    assert [len(x["points"]) for x in lines] == [41, 31, 30] and lines[1]["points"][0]["x"] == 4.0
    assert lines[0]["color"] == {"r": 0x4C / 255, "g": 0xAF / 255, "b": 0x50 / 255, "a": 1.0}
    assert lines[1]["color"]["a"] == 0.45


def test_a_gnss_path_is_geojson_line_strings_styled_by_terrain_and_coloured_fixes(tmp_path: Path) -> None:
    out = write_terrain_mcap(tmp_path / "g.mcap", LogClock("g", 1000.0, 100.0, 1000), path_drawn=_path(geo=True))
    msgs = _messages(out)
    assert set(msgs) == {"/terrain/path", "/terrain/geojson", "/terrain/fix"}
    (geo,) = msgs["/terrain/geojson"]
    collection = json.loads(geo["geojson"])
    assert collection["type"] == "FeatureCollection" and len(collection["features"]) == 3
    first = collection["features"][0]
    assert first["geometry"]["type"] == "LineString" and first["geometry"]["coordinates"][0] == [-71.92, 45.38]
    assert first["properties"]["name"] == "grass" and first["properties"]["style"] == {
        "color": "#4caf50",
        "weight": 4,
        "opacity": 1.0,
    }
    fixes = msgs["/terrain/fix"]
    assert len(fixes) == 100 and fixes[50]["color"]["a"] == 0.45 and fixes[99]["color"]["a"] == 0.7
    assert fixes[10]["timestamp"] == {"sec": 1001, "nsec": 0} and fixes[10]["latitude"] == 45.38 + 1e-6
