"""Terrain as MCAP: the model's terrain and the labels of one log on its own clock, to open beside the log (Foxglove).

One file holds one log. Two logs in one file would put both on one timeline: a log recorded on Monday opened beside
it would play on a timeline that also spans Tuesday's (or, for logs timed from zero, two runs on top of each other).

Messages are JSON with a JSON Schema, so any MCAP reader decodes them without our code:

- ``/terrain`` (the model): one message per sample of the log, at ``t0 + i / rate``: the most probable terrain, its
  probability (``confidence``), the probability of every terrain and, when the model gives one, the drift score.
- ``/terrain/labels`` (the labels): a state topic. A message at the log's start and at every segment boundary says
  which terrain holds from then on (``null``: unlabelled) until ``end_s``. Chosen over one message per segment
  because a reader's "latest message" is then right at any time, also between segments, and a state-transition
  plot draws the labels as bands; it costs two messages per segment at most.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from .errors import WorkbenchError
from .file_names import safe_file_name
from .ingest.time_columns import EPOCH_RANGE_S
from .logs import LogInfo, Segment
from .new_files import check_new_targets, new_file
from .path_mcap import TerrainPath, write_path

PREDICTION_TOPIC = "/terrain"
LABEL_TOPIC = "/terrain/labels"
PROFILE = ""  # no ROS profile: JSON messages are self-describing
BLOCK = 1 << 16  # samples turned into messages at a time
DIGITS = 4  # probabilities and scores, rounded: a tenth of a per cent is more than any figure here means

PREDICTION_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "workbench.TerrainPrediction",
    "description": "The terrain classifier's output for one sample of the log.",
    "type": "object",
    "properties": {
        "terrain": {"type": "string", "description": "The most probable terrain."},
        "confidence": {"type": "number", "minimum": 0, "maximum": 1, "description": "Its probability."},
        "probabilities": {
            "type": "object",
            "additionalProperties": {"type": "number", "minimum": 0, "maximum": 1},
            "description": "The probability of every terrain the model knows, by name.",
        },
        "drift": {
            "type": ["number", "null"],
            "description": "How unlike the labelled data this sample is; above 1 the figures of the model card do "
            "not hold here. null: the model gives no drift score.",
        },
        "sample": {"type": "integer", "minimum": 0, "description": "The sample's index in the log."},
    },
    "required": ["terrain", "confidence", "probabilities", "drift", "sample"],
}
LABEL_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "workbench.TerrainLabel",
    "description": "The labelled terrain from this message's time until end_s (a state: the latest message holds).",
    "type": "object",
    "properties": {
        "terrain": {"type": ["string", "null"], "description": "The labelled terrain; null: unlabelled."},
        "start_s": {"type": "number", "description": "Seconds from the log's start where this state begins."},
        "end_s": {"type": "number", "description": "Seconds from the log's start where it ends."},
        "author": {"type": ["string", "null"]},
        "source": {"type": ["string", "null"], "description": "manual, suggestion, import, seed..."},
    },
    "required": ["terrain", "start_s", "end_s", "author", "source"],
}


@dataclass(frozen=True)
class TerrainPredictions:
    """A model's output over one log: ``probs`` ``(T, K)`` over ``classes``, ``drift`` ``(T,)`` or ``None``."""

    classes: tuple[str, ...]
    probs: np.ndarray
    drift: np.ndarray | None = None


@dataclass(frozen=True)
class LogClock:
    """Where a log's samples lie in time: sample ``i`` at ``t0 + i / rate_hz`` seconds of the source's clock."""

    name: str
    t0: float
    rate_hz: float
    n_samples: int

    @classmethod
    def of(cls, log: LogInfo) -> LogClock:
        """A session log's clock."""
        return cls(log.name, log.t0, log.rate_hz, log.n_samples)

    def span(self) -> str:
        """Where the log lies on its clock, in words: UTC dates for an epoch clock, else seconds."""
        end = self.t0 + max(self.n_samples - 1, 0) / self.rate_hz
        if not EPOCH_RANGE_S[0] <= self.t0 <= EPOCH_RANGE_S[1]:  # as the CSV reader judges epochs
            return f"{self.t0:.3f} s to {end:.3f} s"
        a, b = (datetime.fromtimestamp(t, UTC) for t in (self.t0, end))
        tail = b.strftime("%H:%M:%S.%f")[:-3] if a.date() == b.date() else b.isoformat(" ", "milliseconds")[:-6]
        return f"{a.isoformat(' ', 'milliseconds')[:-6]} to {tail} UTC"

    def ns(self, samples: np.ndarray) -> np.ndarray:
        """Times of sample indices in integer nanoseconds of the source's clock, as MCAP stores them."""
        return round(self.t0 * 1e9) + np.round(np.asarray(samples, np.float64) * (1e9 / self.rate_hz)).astype(np.int64)


def per_log_paths(out: Path, names: Sequence[str], *, each: bool = False) -> list[Path]:
    """The file of each log: ``out`` itself for one log (unless ``each``); for several, ``out`` with the log's name
    before ``.mcap`` (``terrain.mcap`` -> ``terrain.walk_01.mcap``), as one file holds one log's timeline."""
    if len(names) == 1 and not each:
        return [out]
    stem = out.name[: -len(".mcap")] if out.name.lower().endswith(".mcap") else out.name
    paths, seen = [], set()
    for name in names:
        safe = safe_file_name(name, empty="log")
        while safe in seen:
            safe += "_"
        seen.add(safe)
        paths.append(out.with_name(f"{stem}.{safe}.mcap"))
    return paths


def refuse_existing(paths: Sequence[Path]) -> None:
    """Refuse, before anything is computed or written, an output file that could not be written new: one that
    exists (an ``.mcap`` beside a log may be the log itself, and it is never replaced), a link, a missing folder.

    Raises:
        WorkbenchError: Naming the first path refused (``sessions.new_files``).
    """
    check_new_targets(list(paths))


def write_terrain_mcap(
    path: Path,
    clock: LogClock,
    *,
    predictions: TerrainPredictions | None = None,
    labels: Sequence[Segment] | None = None,
    about: dict[str, str] | None = None,
    path_drawn: TerrainPath | None = None,
) -> Path:
    """Write one log's terrain to a new MCAP file, whole or not at all (written aside, given its name when complete).

    Args:
        path: The file to create; an existing one is refused.
        clock: The log's name, start time on the source's clock, rate and length.
        predictions: The model's output per sample, for the ``/terrain`` topic.
        labels: The log's segments (ordered or not; they never overlap), for the ``/terrain/labels`` topic.
        about: Text kept in the file's ``terrain-workbench`` metadata record (model version, session...).
        path_drawn: The log's path coloured by terrain, for Foxglove's 3D and Map panels (``path_mcap``).

    Raises:
        WorkbenchError: The path exists, or the log starts before time zero (MCAP times are unsigned).
    """
    from mcap.writer import Writer

    refuse_existing([path])
    if clock.t0 < 0:
        raise WorkbenchError(f"{path}: log {clock.name!r} starts at {clock.t0} s, before time zero; MCAP has no time")
    with new_file(path) as tmp, open(tmp, "wb") as f:
        writer = Writer(f)
        writer.start(profile=PROFILE, library="terrain-workbench")
        meta = {"log": clock.name, "t0_s": repr(clock.t0), "rate_hz": repr(clock.rate_hz), **(about or {})}
        writer.add_metadata(name="terrain-workbench", data=meta)
        if labels is not None:
            _write_labels(writer, clock, labels)
        if predictions is not None:
            _write_predictions(writer, clock, predictions)
        if path_drawn is not None:
            channels: dict[str, int] = {}

            def channel_of(topic: str, schema: dict) -> int:
                if topic not in channels:
                    channels[topic] = _channel(writer, topic, schema)
                return channels[topic]

            def ns_of(seconds: np.ndarray) -> np.ndarray:
                return np.round((clock.t0 + np.asarray(seconds, np.float64)) * 1e9).astype(np.int64)

            write_path(writer, channel_of, clock.name, path_drawn, ns_of)
        writer.finish()
    return path


def _channel(writer, topic: str, schema: dict) -> int:
    schema_id = writer.register_schema(
        name=schema["title"], encoding="jsonschema", data=json.dumps(schema, indent=1).encode()
    )
    return writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_id)


def _write_predictions(writer, clock: LogClock, p: TerrainPredictions) -> None:
    channel = _channel(writer, PREDICTION_TOPIC, PREDICTION_SCHEMA)
    classes = list(p.classes)
    dumps = json.JSONEncoder(separators=(",", ":")).encode
    for a in range(0, len(p.probs), BLOCK):  # Python numbers for a block at a time: 10 h at 100 Hz would take GBs
        probs = np.asarray(p.probs[a : a + BLOCK], np.float64)  # (B, K)
        best = probs.argmax(-1).tolist()
        confidence = np.round(probs.max(-1), DIGITS).tolist()
        rounded = np.round(probs, DIGITS).tolist()
        drift = (
            [None] * len(probs)
            if p.drift is None
            else np.round(np.asarray(p.drift[a : a + BLOCK], np.float64), DIGITS).tolist()
        )
        times = clock.ns(np.arange(a, a + len(probs))).tolist()
        for j, t in enumerate(times):
            message = {
                "terrain": classes[best[j]],
                "confidence": confidence[j],
                "probabilities": dict(zip(classes, rounded[j], strict=True)),
                "drift": drift[j],
                "sample": a + j,
            }
            writer.add_message(channel, log_time=t, data=dumps(message).encode(), publish_time=t, sequence=a + j)


def label_states(segments: Sequence[Segment], n_samples: int) -> list[tuple[int, int, Segment | None]]:
    """The log cut at every segment boundary: ``(start, stop, segment or None for unlabelled)``, in order."""
    states: list[tuple[int, int, Segment | None]] = []
    at = 0
    for seg in sorted(segments, key=lambda s: s.start):
        if seg.start > at:
            states.append((at, seg.start, None))
        states.append((seg.start, seg.stop, seg))
        at = seg.stop
    if at < n_samples or not states:
        states.append((at, max(n_samples, at), None))
    return states


def _write_labels(writer, clock: LogClock, segments: Sequence[Segment]) -> None:
    channel = _channel(writer, LABEL_TOPIC, LABEL_SCHEMA)
    states = label_states(segments, clock.n_samples)
    times = clock.ns(np.array([a for a, _, _ in states])).tolist()
    for i, ((a, b, seg), t) in enumerate(zip(states, times, strict=True)):
        message = {
            "terrain": seg.terrain if seg else None,
            "start_s": a / clock.rate_hz,
            "end_s": b / clock.rate_hz,
            "author": seg.author if seg else None,
            "source": seg.source if seg else None,
        }
        writer.add_message(channel, log_time=t, data=json.dumps(message).encode(), publish_time=t, sequence=i)
