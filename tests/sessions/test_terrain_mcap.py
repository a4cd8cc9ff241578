"""Terrain MCAP files: read back with the mcap library, times on the log's clock, schemas valid JSON Schema."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from sessions import (
    LABEL_TOPIC,
    PREDICTION_TOPIC,
    LogClock,
    Segment,
    TerrainPredictions,
    WorkbenchError,
    per_log_paths,
    write_terrain_mcap,
)


def read_mcap(path: Path) -> dict[str, list[tuple[int, dict, dict]]]:
    """Per topic: (log time in ns, the message, its schema), every message validated against its JSON Schema."""
    out: dict[str, list[tuple[int, dict, dict]]] = {}
    validators: dict[int, tuple[dict, jsonschema.Draft202012Validator]] = {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            if schema.id not in validators:
                spec = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(spec)
                validators[schema.id] = spec, jsonschema.Draft202012Validator(spec)
            spec, validator = validators[schema.id]
            body = json.loads(message.data)
            validator.validate(body)
            assert message.publish_time == message.log_time
            out.setdefault(channel.topic, []).append((message.log_time, body, spec))
    return out


def segment(start: int, stop: int, terrain: str) -> Segment:
    return Segment(0, 1, start, stop, terrain, "ana", "manual", "", "")


def test_predictions_lie_on_the_log_clock_and_validate(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr("sessions.terrain_mcap.BLOCK", 64)  # messages are made a block at a time: several here
    rng = np.random.default_rng(0)
    probs = rng.dirichlet(np.ones(3), size=250).astype(np.float32)  # (T, K)
    drift = rng.uniform(0, 2, 250).astype(np.float32)
    clock = LogClock("walk", 1_700_000_123.25, 50.0, 250)
    path = write_terrain_mcap(
        tmp_path / "walk.terrain.mcap", clock, predictions=TerrainPredictions(("ice", "grass", "mud"), probs, drift)
    )
    (topic,) = read_mcap(path).values()
    times = np.array([t for t, _, _ in topic])
    expected = 1_700_000_123_250_000_000 + np.arange(250) * 20_000_000
    assert np.abs(times - expected).max() <= 1_000  # float64 seconds hold an epoch time to 0.24 µs
    assert [m["sample"] for _, m, _ in topic] == list(range(250))
    for i in (0, 99, 249):
        m = topic[i][1]
        assert m["terrain"] == ("ice", "grass", "mud")[probs[i].argmax()]
        assert m["confidence"] == pytest.approx(probs[i].max(), abs=1e-4)
        assert [m["probabilities"][k] for k in ("ice", "grass", "mud")] == pytest.approx(probs[i], abs=1e-4)
        assert m["drift"] == pytest.approx(drift[i], abs=1e-4)
    assert set(read_mcap(path)) == {PREDICTION_TOPIC}
    with open(path, "rb") as f:
        (meta,) = make_reader(f).iter_metadata()
    assert meta.name == "terrain-workbench" and meta.metadata["log"] == "walk"


def test_labels_are_a_state_topic_over_the_whole_log(tmp_path: Path) -> None:
    clock = LogClock("walk", 10.0, 100.0, 1000)
    labels = [segment(500, 700, "mud"), segment(100, 300, "ice"), segment(300, 400, "grass")]
    path = write_terrain_mcap(tmp_path / "l.mcap", clock, labels=labels)
    topic = read_mcap(path)[LABEL_TOPIC]
    states = [((t - 10_000_000_000) / 1e7, m["terrain"], m["start_s"], m["end_s"]) for t, m, _ in topic]
    assert states == [
        (0, None, 0.0, 1.0),
        (100, "ice", 1.0, 3.0),
        (300, "grass", 3.0, 4.0),  # adjacent: no unlabelled state between them
        (400, None, 4.0, 5.0),
        (500, "mud", 5.0, 7.0),
        (700, None, 7.0, 10.0),
    ]
    assert topic[1][1]["author"] == "ana" and topic[0][1]["author"] is None


def test_an_existing_output_is_never_replaced(tmp_path: Path) -> None:
    log = tmp_path / "run.mcap"
    log.write_bytes(b"the robot's own log")
    with pytest.raises(WorkbenchError, match=r"run\.mcap: exists already"):
        write_terrain_mcap(log, LogClock("run", 0.0, 10.0, 5), labels=[])
    assert log.read_bytes() == b"the robot's own log"
    assert list(tmp_path.iterdir()) == [log]  # no partial file left either


def test_one_file_per_log(tmp_path: Path) -> None:
    assert per_log_paths(tmp_path / "t.mcap", ["a"]) == [tmp_path / "t.mcap"]
    assert per_log_paths(tmp_path / "t.mcap", ["a/b c", "a_b_c", "x"]) == [
        tmp_path / "t.a_b_c.mcap",
        tmp_path / "t.a_b_c_.mcap",
        tmp_path / "t.x.mcap",
    ]
    assert per_log_paths(tmp_path / "terrain.mcap", ["w"], each=True) == [tmp_path / "terrain.w.mcap"]
