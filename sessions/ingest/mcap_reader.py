"""Read sensor streams from MCAP files recorded by ROS 2 (CDR) or holding JSON-encoded channels."""

from __future__ import annotations

import contextlib
import io
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import IngestError
from ..limits import MAX_IMAGE_MESSAGE_BYTES, MAX_SENSOR_MESSAGE_BYTES
from .base import ChannelSpec, IngestOptions, ParsedLog, Stream
from .cdr_block import decode_block, float64_fields
from .fields import FieldSpec, format_path, get, infer_fields, parse_path, stamp_seconds
from .image_topics import CameraCollector, is_camera
from .mcap_chunks import chunk_records, linear_messages
from .pose_topics import PoseCollector, pose_kind
from .spill import RowBuffer, reorder

MCAP_MAGIC = b"\x89MCAP0\r\n"
BLOCK_MESSAGES = 4096  # messages of a block topic decoded at once (a few MB: memory stays bounded)


@dataclass
class _Topic:
    """What we learned about one topic while reading, and its samples so far."""

    topic: str
    schema: str
    fields: list[FieldSpec] = field(default_factory=list)
    decode: Callable[[bytes], object] | None = None
    unusable: str | None = None  # why the topic gives no channels
    rows: RowBuffer | None = None  # stamps and field values, spilled to disk
    dropped: int = 0
    camera: CameraCollector | None = None  # an image topic: its frames, kept beside the streams
    layout: dict | None = None  # float positions when its messages are a header and floats (cdr_block)
    block: np.ndarray | None = None  # the fields' positions in that layout, once the fields are known
    pending: list[tuple[int, bytes]] = field(default_factory=list)  # (log time, message) not yet decoded
    pose: PoseCollector | None = None  # where the robot was, when the topic carries positions
    pose_decode: Callable[[bytes], object] | None = None  # its decoder where the topic gives no channels


@dataclass(frozen=True)
class TopicReport:
    """For --dry-run: what a topic gives, or why it gives nothing."""

    topic: str
    schema: str
    messages: int
    channels: tuple[tuple[str, str, str], ...]  # (field, unit, ...) for usable topics
    unusable: str | None
    note: str = ""  # what a camera topic gave


# Message types that carry vectors and quaternions but are no robot sensor: estimates, transforms, commands. Their
# fields look like an IMU's to the shape-based inference, so they are left out unless a mapping names the topic.
NOT_SENSORS = {
    "nav_msgs/Odometry": "a state estimate",
    "tf2_msgs/TFMessage": "a transform tree",
    "geometry_msgs/TransformStamped": "a transform",
    "geometry_msgs/PoseWithCovarianceStamped": "a pose estimate",
    "geometry_msgs/PoseStamped": "a pose",
    "geometry_msgs/Pose": "a pose",
    "geometry_msgs/PoseArray": "poses",
    "geometry_msgs/Twist": "a velocity command",
    "geometry_msgs/TwistStamped": "a velocity command or estimate",
    "geometry_msgs/PointStamped": "a point",
    "nav_msgs/Path": "a path",
    "visualization_msgs/Marker": "a visualisation",
    "visualization_msgs/MarkerArray": "a visualisation",
}


def not_a_sensor(schema: str) -> str | None:
    """What a message type is when it is no sensor (ROS 2 ``pkg/msg/Type`` or ROS 1 ``pkg/Type``), else None."""
    return NOT_SENSORS.get(schema.replace("/msg/", "/"))


def _decoder_for(encoding: str, schema) -> Callable[[bytes], object]:
    if encoding == "json":
        return lambda data: json.loads(data)
    if encoding == "cdr":
        if schema is None or schema.encoding != "ros2msg":
            raise ValueError(
                f"CDR channel without a ros2msg schema (schema encoding {getattr(schema, 'encoding', None)!r})"
            )
        from mcap_ros2.decoder import DecoderFactory

        # A fresh factory per channel: it caches decoders by schema id, and ids differ between files.
        # It prints parse errors to stderr; the reason reaches the user through our own message instead.
        sink = io.StringIO()
        try:
            with contextlib.redirect_stdout(sink), contextlib.redirect_stderr(sink):
                decoder = DecoderFactory().decoder_for(encoding, schema)
        except Exception as exc:
            if "---" in str(exc):
                raise ValueError("a service or action schema ('---' sections), which cannot be decoded") from None
            raise ValueError(f"bad ros2msg schema {schema.name!r} ({type(exc).__name__}: {exc})") from None
        if decoder is None:
            raise ValueError("no decoder for this schema")
        return decoder
    raise ValueError(f"message encoding {encoding!r} is not supported (cdr and json are)")


def _read(
    path: Path,
    on_message: Callable[[object, object, object], None],
    reset: Callable[[], None],
    on_bytes: Callable[[int], None] | None,
) -> None:
    """Feed every message to ``on_message``: indexed reader first, streaming reader where that fails."""
    with open(path, "rb") as raw:
        if on_bytes is not None:
            inner, count = on_message, [0]

            def on_message(schema, channel, message) -> None:
                inner(schema, channel, message)
                count[0] += 1
                if count[0] % 4096 == 0:
                    on_bytes(raw.tell())

        head = raw.read(len(MCAP_MAGIC))
        if not head:
            raise IngestError(path, "empty file")
        if head != MCAP_MAGIC:
            raise IngestError(path, "not an MCAP file (wrong magic bytes)", where="byte 0")
        raw.seek(0)
        try:
            _indexed_messages(raw, path, on_message)
            return
        except IngestError:
            raise
        except Exception:
            reset()
        raw.seek(0)
        try:
            linear_messages(raw, path, on_message)
        except IngestError:
            raise
        except Exception as exc:
            detail = str(exc) or type(exc).__name__
            raise IngestError(path, f"truncated or corrupt MCAP: {detail}", where=f"near byte {raw.tell()}") from None
        if on_bytes is not None:
            on_bytes(raw.tell())


def _indexed_messages(raw, path: Path, on_message: Callable[[object, object, object], None]) -> None:
    """Every message of an indexed MCAP, one chunk at a time in file order.

    The library's ``iter_messages`` either decodes every chunk before it yields anything (insert order: the whole
    file in memory) or orders messages through a heap (log-time order: a third of an hour-long ingest spent comparing
    messages). Stamps are sorted after reading anyway, so chunks are read in file order as its own loop does.
    Every chunk is decoded with its size bounded (``mcap_chunks``).
    """
    from mcap.data_stream import ReadDataStream
    from mcap.reader import make_reader
    from mcap.records import Chunk, Message

    reader = make_reader(raw, validate_crcs=True)
    summary = reader.get_summary()
    if summary is None or not summary.chunk_indexes:  # not indexed: read front to back
        raw.seek(0)
        linear_messages(raw, path, on_message)
        return
    for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        raw.seek(index.chunk_start_offset + 1 + 8)  # past the record's opcode and length
        chunk = Chunk.read(ReadDataStream(raw))
        for record in chunk_records(chunk, path=path, where=f"chunk at byte {index.chunk_start_offset}"):
            if isinstance(record, Message):
                channel = summary.channels[record.channel_id]
                on_message(summary.schemas.get(channel.schema_id), channel, record)


def _topic_prefixes(topics: list[str]) -> dict[str, str]:
    """Shortest unique trailing part of each topic name ("/robot/feet/fl" -> "fl")."""
    parts = {t: [p for p in t.strip("/").split("/") if p] or [t] for t in topics}
    out = {}
    for topic, p in parts.items():
        for n in range(1, len(p) + 1):
            cand = "/".join(p[-n:])
            if sum(1 for q in parts.values() if "/".join(q[-n:]) == cand) == 1:
                out[topic] = cand
                break
        else:
            out[topic] = topic
    return out


def read_mcap(
    path: str | Path, options: IngestOptions, *, on_bytes: Callable[[int], None] | None = None
) -> tuple[ParsedLog, list[TopicReport]]:
    """Read an MCAP file into streams, one per usable topic.

    ``on_bytes`` is called now and then with how many bytes of the file have been read.

    Raises:
        IngestError: The file is empty, not MCAP, truncated or corrupt, or has no usable sensor channel.
    """
    path = Path(path)
    return read_topics(
        path,
        options,
        feed=lambda on_message, reset: _read(path, on_message, reset, on_bytes),
        decoder_for=lambda channel, schema: _decoder_for(channel.message_encoding, schema),
        fmt="mcap",
        block_layout=_block_layout,
    )


def _block_layout(channel, schema) -> dict | None:
    """The float layout of a CDR topic whose messages are a header and floats, else None."""
    if channel.message_encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
        return None
    try:
        return float64_fields(schema.data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None


Feed = Callable[[Callable[[object, object, object], None], Callable[[], None]], None]


def read_topics(
    path: Path,
    options: IngestOptions,
    *,
    feed: Feed,
    decoder_for: Callable[[object, object], Callable],
    fmt: str,
    block_layout: Callable[[object, object], dict | None] | None = None,
) -> tuple[ParsedLog, list[TopicReport]]:
    """Streams from any message log: ``feed(on_message, reset)`` calls ``on_message(schema, channel, message)``
    for every message (``schema.name``; ``channel.id``, ``.topic``; ``message.data``, ``.log_time`` in ns), and
    ``decoder_for(channel, schema)`` gives the function that decodes a message's bytes. MCAP and ROS bags share
    this: the same message types, fields and mapping. ``block_layout(channel, schema)``, where given, says which
    topics' messages are a header and floats only (``cdr_block``): those are decoded a block at a time."""
    mapping = options.mapping
    explicit: dict[str, list[ChannelSpec]] = {}
    for spec in mapping.channels:
        explicit.setdefault(spec.source, []).append(spec)
    topics: dict[int, _Topic] = {}
    counts: dict[str, int] = {}

    def reset() -> None:
        topics.clear()
        counts.clear()

    def on_message(schema, channel, message) -> None:
        counts[channel.topic] = counts.get(channel.topic, 0) + 1
        t = topics.get(channel.id)
        if t is None:
            t = topics[channel.id] = _Topic(channel.topic, schema.name if schema else "")
            camera = is_camera(t.schema)
            if channel.topic in mapping.ignore or (explicit and channel.topic not in explicit and not camera):
                t.unusable = "ignored by the mapping file"
            elif camera and not options.camera_fps > 0:
                t.unusable = "camera frames not kept (camera_fps 0)"
            elif channel.topic not in explicit and not_a_sensor(t.schema):
                t.unusable = (
                    f"not a sensor: {t.schema} is {not_a_sensor(t.schema)} (name the topic in a mapping file to read "
                    "it anyway)"
                )
            else:
                try:
                    t.decode = decoder_for(channel, schema)
                except Exception as exc:
                    t.unusable = f"cannot decode: {exc}"
                if camera and not t.unusable:
                    t.camera = CameraCollector(t.topic, t.schema, fps=options.camera_fps)
                elif block_layout is not None and not t.unusable:
                    t.layout = block_layout(channel, schema)
            if channel.topic not in mapping.ignore and not camera:
                # a pose type by its name; any other topic may be a GNSS driver's own fix, found by its fields
                t.pose = PoseCollector(t.topic, t.schema, pose_kind(t.schema), child=mapping.tf_child)
                t.pose_decode = t.decode
                if t.pose_decode is None:  # read for its positions alone; undecodable: the sensor side says why
                    with contextlib.suppress(Exception):
                        t.pose_decode = decoder_for(channel, schema)
        if t.pose is not None and t.pose_decode is not None and (t.unusable or t.decode is None):
            _feed_pose(t, message)  # a pose topic read for its positions alone
        if t.unusable:
            return
        size = len(message.data)
        if t.camera is not None:
            if size > MAX_IMAGE_MESSAGE_BYTES:  # one hostile frame costs the frame
                t.camera.skip(f"a message of {size:,} bytes, over the limit of {MAX_IMAGE_MESSAGE_BYTES:,}")
            elif t.camera.wants(message.log_time):  # frames past the rate cap are never decoded
                try:
                    msg = t.decode(message.data)
                except Exception as exc:
                    t.camera.skip(f"cannot decode: {exc}")
                else:
                    t.camera.add(msg, message.log_time)
            return
        if size > MAX_SENSOR_MESSAGE_BYTES:
            raise IngestError(
                path,
                f"a {t.schema or 'sensor'} message of {size:,} bytes, over the limit of {MAX_SENSOR_MESSAGE_BYTES:,} "
                "for a topic read as sensor channels (sessions/limits.py)",
                where=f"topic {t.topic}, log time {message.log_time}",
            )
        if t.block is not None:
            t.pending.append((message.log_time, bytes(message.data)))
            if len(t.pending) >= BLOCK_MESSAGES:
                flush(t)
            return
        add(t, message.data, message.log_time)

    def add(t: _Topic, data: bytes, log_time: int) -> None:
        """One message through the library's decoder."""
        try:
            msg = t.decode(data)
        except Exception as exc:
            if not t.fields:
                t.unusable = f"cannot decode: {exc}"
                return
            if options.allow_gaps:
                t.dropped += 1
                return
            raise IngestError(
                path,
                f"message cannot be decoded: {exc}",
                where=f"topic {t.topic}, log time {log_time}",
            ) from None
        if t.pose is not None and t.pose.add(msg, log_time) is False:
            t.pose = None
        if not t.fields:
            if t.topic in explicit:
                t.fields = [FieldSpec(parse_path(s.field), s.name or s.field, s.unit, None) for s in explicit[t.topic]]
            else:
                t.fields = infer_fields(msg)
            if not t.fields:
                t.unusable = f"no sensor fields recognised in {t.schema or 'its messages'}"
                return
            t.rows = RowBuffer(len(t.fields))
            if t.layout is not None and t.pose is None and all(f.header in (None, ()) for f in t.fields):
                paths = [tuple(f.path) for f in t.fields]
                if all(p in t.layout for p in paths):  # the next messages go a block at a time
                    t.block = np.asarray([t.layout[p] for p in paths])
        try:
            row = [float(get(msg, f.path)) for f in t.fields]
        except (AttributeError, KeyError, IndexError, TypeError, ValueError) as exc:
            raise IngestError(
                path,
                f"field missing or not numeric: {exc}",
                where=f"topic {t.topic}, log time {log_time}",
            ) from None
        if not all(np.isfinite(row)):
            if options.allow_gaps:
                t.dropped += 1
                return
            raise IngestError(
                path,
                "NaN or infinite value (use --allow-gaps to record it as a gap)",
                where=f"topic {t.topic}, log time {log_time}",
            )
        header = t.fields[0].header
        stamp = stamp_seconds(msg, header) if header is not None else None
        t.rows.append(stamp if stamp is not None else log_time * 1e-9, row)

    def flush(t: _Topic) -> None:
        """Decode the pending messages of a block topic; any that do not fit the layout go through ``add``."""
        pending, t.pending = t.pending, []
        if not pending or t.rows is None or t.block is None or t.layout is None:
            return
        log_ns = np.fromiter((p[0] for p in pending), np.int64, len(pending))
        stamps, values, ok = decode_block([p[1] for p in pending], len(t.layout))
        for i in np.flatnonzero(~ok):
            add(t, pending[i][1], int(log_ns[i]))
        rows = values[ok][:, t.block]  # (n, fields)
        use = np.isfinite(stamps[ok]) if t.fields[0].header is not None else np.zeros(int(ok.sum()), bool)
        times = np.where(use, stamps[ok], log_ns[ok] * 1e-9)
        finite = np.isfinite(rows).all(axis=1)
        if not finite.all():
            if not options.allow_gaps:
                raise IngestError(
                    path,
                    "NaN or infinite value (use --allow-gaps to record it as a gap)",
                    where=f"topic {t.topic}, log time {int(log_ns[ok][~finite][0])}",
                )
            t.dropped += int((~finite).sum())
        t.rows.append_block(times[finite], rows[finite])

    feed(on_message, reset)
    for t in topics.values():
        flush(t)

    usable = [t for t in topics.values() if not t.unusable and t.rows is not None and len(t.rows)]
    reports = [
        TopicReport(
            t.topic,
            t.schema,
            counts.get(t.topic, 0),
            tuple((format_path(f.path), f.unit, "") for f in t.fields) if not t.unusable else (),
            t.unusable,
            t.camera.note if t.camera is not None else "",
        )
        for t in topics.values()
    ]
    cameras = tuple(c for t in topics.values() if t.camera is not None and (c := t.camera.result()) is not None)
    poses = tuple(track for t in topics.values() if t.pose is not None for track in t.pose.tracks())
    if not usable:
        if not topics:
            reason = "no messages"
        else:
            reason = "; ".join(f"{t.topic}: {t.unusable or 'no messages'}" for t in topics.values())
        raise IngestError(path, f"no usable sensor channel ({reason})")
    prefixes = _topic_prefixes([t.topic for t in usable])
    streams = []
    for t in usable:
        times, values = t.rows.times(), t.rows.values()  # values stay on disk
        if (np.diff(times) < 0).any():  # logs are not always in stamp order
            order = np.argsort(times, kind="stable")
            times, values = times[order], reorder(values, order)
        nonzero = values.column_any()
        keep = [i for i, f in enumerate(t.fields) if not ("torque" in f.name and not nonzero[i])]
        if len(keep) < values.shape[1]:
            values = values.select(keep)
        prefix = prefixes[t.topic]
        streams.append(
            Stream(
                name=prefix,
                times=times,
                values=values,
                channels=tuple(f"{prefix}/{t.fields[i].name}" for i in keep),
                units=tuple(t.fields[i].unit for i in keep),
                sources=tuple(f"{t.topic}:{format_path(t.fields[i].path)}" for i in keep),
            )
        )
    reference = _sidecar_reference(path)
    return (
        ParsedLog(
            name=path.stem,
            source_path=str(path),
            files=(str(path),),
            format=fmt,
            streams=tuple(streams),
            reference=reference,
            cameras=cameras,
            poses=poses,
            notes=tuple(_pose_notes(poses)),
        ),
        reports,
    )


def _feed_pose(t: _Topic, message) -> None:
    """A message of a topic read for its positions alone, decoded for them (an undecodable one is counted)."""
    if len(message.data) > MAX_SENSOR_MESSAGE_BYTES:  # no position is that large: never decoded
        t.pose.failed += 1
        return
    try:
        msg = t.pose_decode(message.data)
    except Exception:
        if t.pose.kind is None:  # not known to carry positions: not tried again
            t.pose = None
        else:
            t.pose.failed += 1
        return
    if t.pose.add(msg, message.log_time) is False:
        t.pose = None


def _pose_notes(poses: tuple) -> list[str]:
    """One line per track that lost poses as impossible, naming how many."""
    return [
        f"positions of {p.source}: {p.dropped:,} of {p.dropped + len(p.times):,} dropped as impossible (not "
        "finite, time going back, out of range or a jump)"
        for p in poses
        if p.dropped
    ]


def _sidecar_reference(path: Path) -> tuple[tuple[float, float, str], ...]:
    """Reference truth from ``<stem>.truth.json`` beside the log (the demo generator writes one)."""
    side = path.with_name(path.stem + ".truth.json")
    if not side.exists():
        return ()
    try:
        doc = json.loads(side.read_text())
        return tuple((float(s["start"]), float(s["stop"]), str(s["terrain"])) for s in doc["segments"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise IngestError(side, f"unreadable truth sidecar: {exc}") from None
