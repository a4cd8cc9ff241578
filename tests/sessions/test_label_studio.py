"""Label Studio in and out: tasks with timeserieslabels regions on the log's clock, round-tripped through a file
shaped like Label Studio's documented JSON export."""

from __future__ import annotations

import copy
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sessions import Session
from tests.conftest import new_session
from workbench.cli import main

EPOCH = 1_700_000_000.0


def write_logs(folder: Path) -> list[Path]:
    """Two small CSV logs at 100 Hz: one timed in epoch seconds, one from 12.5 s."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, t0 in (("field", EPOCH), ("lab", 12.5)):
        t = t0 + np.arange(1500) / 100.0
        lines = [f"{x:.2f},{np.sin(x):.4f},{np.cos(3 * x):.4f}" for x in t]
        (folder / f"{name}.csv").write_text("time,ax,wz\n" + "\n".join(lines) + "\n")
        paths.append(folder / f"{name}.csv")
    return paths


def labelled(path: Path, logs: list[Path]) -> Session:
    s = new_session(path)
    field, lab = s.ingest(logs)
    s.add_segment(field.id, 100, 400, "grass", author="ana")
    s.add_segment(field.id, 400, 650, "gravel", author="ana")
    s.add_segment(lab.id, 1000, 1490, "sand", author="ben")
    return s


def as_label_studio_export(tasks: list[dict]) -> list[dict]:
    """What Label Studio's "JSON" export gives for imported tasks once annotated: ids, timestamps and bookkeeping
    around each task and annotation, and the data file under Label Studio's upload name when it was uploaded."""
    out = []
    for k, task in enumerate(copy.deepcopy(tasks), start=1):
        annotations = [
            {
                "id": 100 + k,
                "completed_by": 1,
                "result": a["result"],
                "was_cancelled": False,
                "ground_truth": False,
                "created_at": "2026-11-26T10:00:00.000000Z",
                "updated_at": "2026-11-26T10:05:00.000000Z",
                "lead_time": 41.2,
                "prediction": {},
                "result_count": len(a["result"]),
                "task": k,
                "project": 1,
            }
            for a in task["annotations"]
        ]
        out.append(
            {
                "id": k,
                "annotations": annotations,
                "file_upload": None,
                "drafts": [],
                "predictions": [],
                "data": task["data"],
                "meta": {},
                "created_at": "2026-11-26T09:00:00.000000Z",
                "updated_at": "2026-11-26T10:05:00.000000Z",
                "inner_id": k,
                "total_annotations": len(annotations),
                "cancelled_annotations": 0,
                "total_predictions": 0,
                "project": 1,
                "updated_by": 1,
            }
        )
    return out


@pytest.fixture
def logs(tmp_path: Path) -> list[Path]:
    return write_logs(tmp_path / "logs")


def test_export_is_one_task_per_log_on_the_logs_clock(tmp_path: Path, logs: list[Path], monkeypatch) -> None:
    monkeypatch.setattr("sessions.label_studio.BLOCK", 256)  # a log's CSV is written in blocks: several here
    with labelled(tmp_path / "a", logs) as s:
        written = s.export_label_studio(tmp_path / "ls.json")
    tasks = json.loads((tmp_path / "ls.json").read_text())
    assert [t["data"]["log"] for t in tasks] == ["field", "lab"]
    assert tasks[0]["data"]["csv"] == "/data/local-files/?d=ls-files/field.csv"
    regions = [r for r in tasks[0]["annotations"][0]["result"]]
    assert all(r["type"] == "timeserieslabels" and r["to_name"] == "ts" for r in regions)
    assert [(r["value"]["start"], r["value"]["end"], r["value"]["timeserieslabels"]) for r in regions] == [
        (pytest.approx(EPOCH + 1.0), pytest.approx(EPOCH + 4.0), ["grass"]),
        (pytest.approx(EPOCH + 4.0), pytest.approx(EPOCH + 6.5), ["gravel"]),
    ]
    csv = pd.read_csv(tmp_path / "ls-files" / "field.csv")
    assert list(csv.columns) == ["time", "ax", "wz"] and len(csv) == 1500
    assert csv["time"].iloc[100] == pytest.approx(EPOCH + 1.0, abs=1e-6)  # a region's start is a row's time
    assert np.allclose(np.diff(csv["time"]), 0.01, atol=1e-6)  # no row lost or repeated between blocks
    with Session.open(tmp_path / "a") as s:
        assert np.allclose(csv[["ax", "wz"]].to_numpy(), s.samples(s.logs()[0].id), atol=1e-6)
    config = ET.fromstring((tmp_path / "ls-files" / "labeling-config.xml").read_text())
    labels = [e.get("value") for e in config.iter("Label")]
    assert labels == [t.name for t in Session.open(tmp_path / "a").terrains()]
    assert [e.get("column") for e in config.iter("Channel")] == ["ax", "wz"]
    assert config.find("TimeSeries").get("timeColumn") == "time"
    assert {p.name for p in written} == {"ls.json", "labeling-config.xml", "field.csv", "lab.csv"}


def test_logs_on_unix_time_get_a_date_axis_and_regions_in_ms(tmp_path: Path, logs: list[Path]) -> None:
    with new_session(tmp_path / "a") as a:
        (field,) = a.ingest(logs[:1])  # only the log timed in epoch seconds
        a.add_segment(field.id, 100, 400, "grass", author="ana")
        a.add_segment(field.id, 400, 650, "gravel", author="ana")
        a.export_label_studio(tmp_path / "ls.json")
        want = [(s.start, s.stop, s.terrain) for s in a.segments()]
    config = ET.fromstring((tmp_path / "ls-files" / "labeling-config.xml").read_text()).find("TimeSeries")
    assert config.get("timeFormat") == "%s.%L"  # d3 parses ms, not µs (Label Studio 1.23 refuses "%f")
    assert pd.read_csv(tmp_path / "ls-files" / "field.csv", dtype={"time": str})["time"][100] == f"{EPOCH + 1:.3f}"
    tasks = json.loads((tmp_path / "ls.json").read_text())
    value = tasks[0]["annotations"][0]["result"][0]["value"]
    assert (value["start"], value["end"]) == (pytest.approx((EPOCH + 1.0) * 1e3), pytest.approx((EPOCH + 4.0) * 1e3))
    (tmp_path / "export.json").write_text(json.dumps(as_label_studio_export(tasks)))
    b = new_session(tmp_path / "b")
    b.ingest(logs[:1])
    b.import_labels(tmp_path / "export.json", author="me")
    assert [(s.start, s.stop, s.terrain) for s in b.segments()] == want


@pytest.mark.parametrize("clock", ["log", "ms", "from-start"])
def test_a_label_studio_export_imports_back_to_the_same_segments(tmp_path: Path, logs: list[Path], clock) -> None:
    with labelled(tmp_path / "a", logs) as a:
        a.export_label_studio(tmp_path / "ls.json")
        want = [(s.start, s.stop, s.terrain) for s in a.segments()]
        t0 = {log.name: log.t0 for log in a.logs()}
    tasks = as_label_studio_export(json.loads((tmp_path / "ls.json").read_text()))
    del tasks[1]["data"]["log"]  # a task of the user's own project: its log known by its uploaded file's name
    tasks[1]["data"]["csv"] = "/data/upload/1/5f3a9c2e-lab.csv"
    tasks[0]["annotations"][0]["result"].append(  # another control of the same project: not a terrain span
        {"from_name": "quality", "to_name": "ts", "type": "choices", "value": {"choices": ["good"]}}
    )
    for task in tasks:
        log = task["data"].get("log", "lab")
        for r in task["annotations"][0]["result"]:
            if r["type"] != "timeserieslabels":
                continue
            v = r["value"]
            if clock == "ms":  # a project whose time column is a date exports milliseconds
                v["start"], v["end"] = v["start"] * 1e3, v["end"] * 1e3
            elif clock == "from-start":
                v["start"], v["end"] = v["start"] - t0[log], v["end"] - t0[log]
    (tmp_path / "export.json").write_text(json.dumps(tasks))
    b = new_session(tmp_path / "b")
    b.ingest(logs)
    imported = b.import_labels(tmp_path / "export.json", author="me").segments
    assert [(s.start, s.stop, s.terrain) for s in b.segments()] == want
    assert {s.author for s in imported} == {"label-studio user 1"} and {s.source for s in imported} == {"import"}


def test_a_malformed_label_studio_file_is_one_line_and_imports_nothing(tmp_path: Path, logs: list[Path], capsys):
    with labelled(tmp_path / "a", logs) as a:
        a.export_label_studio(tmp_path / "ls.json")
    good = as_label_studio_export(json.loads((tmp_path / "ls.json").read_text()))
    b = new_session(tmp_path / "b")
    b.ingest(logs)
    b.close()

    def broken(change) -> Path:
        tasks = copy.deepcopy(good)
        change(tasks)
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(tasks))
        return path

    def value(tasks):
        return tasks[1]["annotations"][0]["result"][0]["value"]

    cases = {
        "task 1 (id 1): names no log of this session": lambda t: t[0].update(data={"csv": "/data/upload/1/x.csv"}),
        "task 2 (id 2): an instant at": lambda t: value(t).update(instant=True),
        "task 2 (id 2): region start/end 'soon'/": lambda t: value(t).update(start="soon"),
        "task 2 (id 2): region 1e+06 to 2e+06 lies outside log 'lab'": lambda t: value(t).update(start=1e6, end=2e6),
        "task 2 (id 2): a region needs one terrain": lambda t: value(t).update(timeserieslabels=[]),
        "task 1 (id 1): annotations is not a list": lambda t: t[0].update(annotations={"result": []}),
        "task 2 (id 2), region 1: unknown terrain 'lava'": lambda t: value(t).update(timeserieslabels=["lava"]),
        "task 1 (id 1), region 2: overlaps segment #": lambda t: t[0]["annotations"][0]["result"][1]["value"].update(
            timeserieslabels=["sand"], start=EPOCH + 3.0
        ),
    }
    for message, change in cases.items():
        path = broken(change)
        assert main(["labels", "import", str(tmp_path / "b"), str(path)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"error: {path}: {message}" in err, err
    with Session.open(tmp_path / "b") as b:
        assert b.segments() == [] and b.history() == []
    (tmp_path / "nested.json").write_text(json.dumps([{"data": "walk.csv", "annotations": []}]))
    assert main(["labels", "import", str(tmp_path / "b"), str(tmp_path / "nested.json")]) == 2
    assert "or a Label Studio export (tasks with data and annotations)" in capsys.readouterr().err


def test_cli_export_for_label_studio(tmp_path: Path, logs: list[Path], capsys) -> None:
    labelled(tmp_path / "a", logs).close()
    out = tmp_path / "ls.json"
    args = ["labels", "export", str(tmp_path / "a"), "--out", str(out), "--format", "label-studio"]
    assert main([*args, "--url-prefix", "https://files.example/"]) == 0
    said = capsys.readouterr().out
    assert f"wrote {out}: 2 task(s), one per log, 3 labelled region(s)" in said
    assert json.loads(out.read_text())[1]["data"]["csv"] == "https://files.example/lab.csv"
    as_csv = ["labels", "export", str(tmp_path / "a"), "--out", str(tmp_path / "ls.csv"), "--format", "label-studio"]
    assert main(as_csv) == 2
    assert "Label Studio's import is JSON" in capsys.readouterr().err
