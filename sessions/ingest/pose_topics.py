"""A message log's pose topics read into pose tracks beside its sensor streams (``mcap_reader.read_topics``)."""

from __future__ import annotations

from array import array
from dataclasses import dataclass, field

import numpy as np

from .fields import get, stamp_seconds
from .poses import (
    POSE_PATHS,
    PoseTrack,
    base_frame,
    clean,
    fix_of,
    gnss_fields,
    position_of,
    tf_translations,
)

TF_TYPES = ("tf2_msgs/TFMessage",)


def pose_kind(schema: str) -> str | None:
    """The track a topic of this type gives by its type alone (``"gnss"`` is found by field names, once decoded)."""
    plain = schema.replace("/msg/", "/")
    if plain in POSE_PATHS:
        return POSE_PATHS[plain][1]
    if plain in TF_TYPES:
        return "tf"
    return None


@dataclass
class PoseCollector:
    """One topic's positions as they are read; a ``/tf`` topic's per child frame."""

    topic: str
    schema: str
    kind: str | None  # None: not known yet (a GNSS message of a driver's own type is found by its fields)
    child: str | None = None  # /tf: the child frame the mapping names
    gnss: tuple[str, str, str | None] | None = None
    frame: str = ""
    # flat float64 arrays, 32 bytes a pose (Python tuples took ~150: a log of millions of poses stays small)
    times: array = field(default_factory=lambda: array("d"))
    rows: array = field(default_factory=lambda: array("d"))  # x, y, z (or latitude, longitude, altitude) in turn
    tf: dict[tuple[str, str], tuple[array, array]] = field(default_factory=dict)
    failed: int = 0

    def add(self, message: object, log_time_ns: int) -> bool:
        """Take a decoded message's position; ``False`` when the topic turns out to carry none (stop feeding it)."""
        stamp = stamp_seconds(message, ())
        t = stamp if stamp is not None else log_time_ns * 1e-9
        try:
            if self.kind == "tf":
                for parent, child, xyz, at in tf_translations(message, self.child):
                    times, rows = self.tf.setdefault((parent, child), (array("d"), array("d")))
                    times.append(at if at is not None else t)
                    rows.extend(xyz)
                return True
            if self.kind is None:
                self.gnss = gnss_fields(message)
                if self.gnss is None:
                    return False
                self.kind = "gnss"
            if self.kind == "gnss":
                value = fix_of(message, self.gnss)
                self.frame = "wgs84"
            else:
                value = position_of(self.schema, message)
                if not self.frame:
                    self.frame = _frame_of(message)
        except (AttributeError, KeyError, IndexError, TypeError, ValueError):
            self.failed += 1
            return True
        if value is not None:
            self.times.append(t)
            self.rows.extend(value)
        return True

    def tracks(self) -> list[PoseTrack]:
        """What was read, each track cleaned of impossible poses (:func:`poses.clean`)."""
        if self.kind == "tf":
            children = {c for _, c in self.tf}
            chosen = self.child or base_frame(children)
            out = []
            for (parent, child), (times, rows) in self.tf.items():
                if child == chosen and times:
                    out.append(_track("tf", f"{self.topic}:{child}", parent, times, rows, self.failed))
            return [clean(t) for t in out]
        if not self.times or self.kind is None:
            return []
        return [clean(_track(self.kind, self.topic, self.frame, self.times, self.rows, self.failed))]


def _track(kind: str, source: str, frame: str, times: array, rows: array, failed: int) -> PoseTrack:
    xyz = np.frombuffer(rows, np.float64).reshape(-1, 3).copy()  # (N, 3)
    return PoseTrack(kind, source, frame or "odom", np.frombuffer(times, np.float64).copy(), xyz, failed)


def _frame_of(message: object) -> str:
    try:
        return str(get(message, ("header", "frame_id"))).lstrip("/")
    except (AttributeError, KeyError, TypeError):
        return ""
