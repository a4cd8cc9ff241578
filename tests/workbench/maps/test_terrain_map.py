"""Where each terrain was: each log's path coloured by its labels, else the model's sure answer, else grey."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from sessions import Session
from workbench.maps import LABEL, MODEL, UNSURE, TerrainMap, panel_of


def _gnss_run(path: Path, *, east_m: float, seconds: float = 120.0, rate: float = 50.0) -> None:
    """A straight drive north at 1 m/s, ``east_m`` east of the field's corner."""
    rng = np.random.default_rng(len(path.name))
    t = np.arange(int(seconds * rate)) / rate
    frame = pd.DataFrame({"time": t, "az": rng.normal(size=len(t))})
    frame["lat"] = 45.38 + t / 111_195.0
    frame["lon"] = -71.92 + east_m / 78_200.0
    frame.to_csv(path, index=False)


def _session(tmp_path: Path) -> Session:
    s = Session.create(tmp_path / "s")
    for name in ("grass", "gravel"):
        s.add_terrain(name)
    _gnss_run(tmp_path / "a.csv", east_m=0.0)
    _gnss_run(tmp_path / "b.csv", east_m=20.0)
    s.ingest([tmp_path / "a.csv", tmp_path / "b.csv"])
    a = s.logs()[0]
    s.add_segment(log_id=a.id, start=0, stop=3000, terrain="grass", author="me")  # its first minute
    return s


def test_a_path_is_labelled_where_labelled_the_models_where_sure_and_grey_elsewhere(tmp_path: Path) -> None:
    s = _session(tmp_path)
    a, b = s.logs()
    probs = np.zeros((b.n_samples, 2), np.float32)
    probs[: b.n_samples // 2] = (0.1, 0.9)  # sure of gravel in its first half
    probs[b.n_samples // 2 :] = (0.5, 0.5)  # unsure after
    drawing = TerrainMap(s, [a, b])
    drawing.add(b, probs, ["grass", "gravel"])
    out = drawing.write(tmp_path / "map.png")
    keep = os.environ.get("WORKBENCH_KEEP_MAP")  # a path: look at the picture
    if keep:
        shutil.copy(out, keep)
    assert out is not None and out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    pa, pb = drawing.paths[a.id], drawing.paths[b.id]
    assert set(pa.source[pa.times < 59.9]) == {LABEL} and set(pa.terrain[pa.times < 59.9]) == {0}
    assert set(pa.source[pa.times > 60.1]) == {UNSURE}  # never scored, not labelled there
    assert set(pb.source[pb.times < 59.9]) == {MODEL} and set(pb.terrain[pb.times < 59.9]) == {1}
    assert set(pb.source[pb.times > 60.1]) == {UNSURE} and set(pb.terrain[pb.times > 60.1]) == {-1}
    # both runs in one panel, in metres from the first fix: b drives 20 m east of a
    assert panel_of(pa) == panel_of(pb) == "wgs84"
    assert np.allclose(pa.xy[0], (0.0, 0.0), atol=0.01) and np.allclose(pb.xy[0], (20.0, 0.0), atol=0.05)
    assert np.allclose(pa.xy[-1, 1], 119.98, atol=0.05)
    assert drawing.words().startswith(
        "2 of 2 logs have positions (gnss); of the 6,000 poses drawn, 25% labelled"
    )  # 3,000 a log


def test_no_positions_no_picture(tmp_path: Path) -> None:
    s = Session.create(tmp_path / "s")
    pd.DataFrame({"time": np.arange(100) / 10, "a": np.sin(np.arange(100))}).to_csv(tmp_path / "c.csv", index=False)
    s.ingest([tmp_path / "c.csv"])
    assert TerrainMap(s, s.logs()).write(tmp_path / "map.png") is None and not (tmp_path / "map.png").exists()


def test_the_mcap_label_export_adds_each_labelled_logs_path_coloured_by_its_labels(tmp_path: Path, capsys) -> None:
    from tests.sessions.test_path_mcap import _messages
    from workbench.cli import main

    _session(tmp_path).close()
    assert main(["labels", "export", str(tmp_path / "s"), "--out", str(tmp_path / "labels.mcap")]) == 0
    assert (
        "topics /terrain/labels, /terrain/path, /terrain/geojson, /terrain/fix, 1 segment(s)" in capsys.readouterr().out
    )
    msgs = _messages(tmp_path / "labels.mcap")  # the one labelled log, a; every message valid against Foxglove's
    features = json.loads(msgs["/terrain/geojson"][0]["geojson"])["features"]
    assert [(f["properties"]["name"], f["properties"]["style"]["color"]) for f in features] == [
        ("grass", "#4caf50"),
        ("unsure", "#cfcfcf"),
    ]
