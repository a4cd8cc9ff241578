"""Read ROS 1 bags (``.bag``) and ROS 2 SQLite bags (``.db3``, or their folder) with the pure-Python ``rosbags``
library: no ROS installation. Messages go through the same topic handling as MCAP (``read_topics``): the same
message types, fields, names and mapping file.

``rosbags`` decompresses a ROS 1 chunk (bz2, lz4) and a ROS 2 message (zstd) whole, to whatever it holds. Its
decompressors are looked up in tables (``rosbag1.reader.decompressors``, ``rosbag2.reader.zstd``); the bounded ones
of ``bounded_decode`` take their place while a bag is read, so a chunk stops at ``MAX_CHUNK_BYTES`` and a message at
``MAX_IMAGE_MESSAGE_BYTES``."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from ..errors import IngestError
from ..limits import MAX_CHUNK_BYTES, MAX_IMAGE_MESSAGE_BYTES
from .base import IngestOptions, ParsedLog
from .bounded_decode import DecodedTooLarge, decompress_within
from .mcap_reader import TopicReport, read_topics

BAG_SUFFIXES = (".bag", ".db3")


@dataclass(frozen=True)
class _Schema:
    name: str


@dataclass(frozen=True)
class _Channel:
    id: int
    topic: str


@dataclass(frozen=True)
class _Message:
    data: bytes
    log_time: int


def bag_root(path: Path) -> Path:
    """What ``rosbags`` opens: a ``.bag`` file itself, the folder of a ROS 2 bag for a ``.db3`` inside one."""
    return path.parent if path.suffix.lower() == ".db3" else path


class _BoundedZstd:
    """What ``rosbags.rosbag2.reader`` calls as ``zstd.decompress`` for a compressed message."""

    @staticmethod
    def decompress(data: bytes) -> bytes:
        return decompress_within(data, "zstd", MAX_IMAGE_MESSAGE_BYTES, "a bag message")


def _bound_decompression() -> None:
    """Put the bounded decompressors in ``rosbags``' tables (idempotent)."""
    from rosbags.rosbag1 import reader as ros1
    from rosbags.rosbag2 import reader as ros2

    for kind in ("bz2", "lz4"):
        ros1.decompressors[kind] = lambda data, kind=kind: decompress_within(data, kind, MAX_CHUNK_BYTES, "a bag chunk")
    ros2.zstd = _BoundedZstd  # type: ignore[assignment]


def _too_large(exc: BaseException) -> DecodedTooLarge | None:
    """The bound a bag passed, whether rosbags raised it as it is or wrapped it."""
    while exc is not None:
        if isinstance(exc, DecodedTooLarge):
            return exc
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return None


def read_bag(
    path: str | Path, options: IngestOptions, *, on_bytes: Callable[[int], None] | None = None
) -> tuple[ParsedLog, list[TopicReport]]:
    """Read a ROS 1 or ROS 2 bag into streams, one per usable topic.

    Raises:
        IngestError: The bag cannot be opened or read, or has no usable sensor channel.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if path.stat().st_size == 0:
        raise IngestError(path, "empty file")
    root = bag_root(path)
    _bound_decompression()
    # bags written without their message definitions (older ROS 2) fall back on the standard types
    default = get_typestore(Stores.ROS2_HUMBLE)
    try:
        reader = AnyReader([root], default_typestore=default)
        reader.open()
    except Exception as exc:
        raise IngestError(path, f"not a readable ROS bag: {type(exc).__name__}: {exc}") from None

    def feed(on_message, reset) -> None:
        try:
            for connection, timestamp, raw in reader.messages():
                schema, channel = _Schema(connection.msgtype), _Channel(connection.id, connection.topic)
                on_message(schema, channel, _Message(raw, int(timestamp)))
        except IngestError:
            raise
        except Exception as exc:
            bound = _too_large(exc)
            if bound is not None:
                raise IngestError(
                    path, f"{bound.what} decodes to more than {bound.limit:,} bytes, the limit (sessions/limits.py)"
                ) from None
            raise IngestError(path, f"truncated or corrupt bag: {type(exc).__name__}: {exc}") from None

    def decoder_for(channel: _Channel, schema: _Schema) -> Callable[[bytes], object]:
        return lambda data: reader.deserialize(data, schema.name)

    try:
        parsed, reports = read_topics(path, options, feed=feed, decoder_for=decoder_for, fmt="bag")
    finally:
        reader.close()
    if on_bytes is not None:  # rosbags gives no byte position while reading: the whole file at the end
        on_bytes(path.stat().st_size)
    return parsed, reports
