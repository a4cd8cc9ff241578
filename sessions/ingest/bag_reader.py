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


ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
SQLITE_MAGIC = b"SQLite format 3\x00"
ROS1_MAGIC = b"#ROSBAG V2.0\n"


def _one_line(exc: BaseException) -> str:
    """A library's message on one line (rosbags quotes a whole message definition in its parse errors)."""
    text = " ".join(str(exc).split())
    return text if len(text) <= 300 else text[:300] + "…"


def _check_magic(path: Path) -> None:
    """Refuse a file that is not the kind its name says before rosbags opens it: a zstd-compressed bag renamed
    ``.db3`` reached rosbags' file decompression and failed with an AttributeError."""
    with open(path, "rb") as f:
        head = f.read(16)
    if head.startswith(ZSTD_MAGIC):
        raise IngestError(
            path,
            "compressed with zstd as a whole file (a ROS 2 bag compressed file by file?); decompress it first "
            "(`zstd -d`), then ingest the .db3 with its metadata.yaml",
        )
    suffix = path.suffix.lower()
    if suffix == ".db3" and not head.startswith(SQLITE_MAGIC):
        raise IngestError(path, "not a ROS 2 bag: a .db3 file is an SQLite database, and this one has no SQLite header")
    if suffix == ".bag" and not head.startswith(ROS1_MAGIC[: len(head)]):
        raise IngestError(path, "not a ROS 1 bag: no '#ROSBAG V2.0' header")


def _check_index(path: Path, reader) -> None:
    """Refuse a ROS 1 bag whose index lists a chunk more than once: rosbags reads it as often as it is listed, every
    message that many times (17 chunks listed 1,000 times each: 126 s and 729 MB for a 3 MB file)."""
    for bag in getattr(reader, "readers", ()):
        infos = getattr(bag, "chunk_infos", None)
        if not infos:
            continue
        positions = [info.pos for info in infos]
        if len(set(positions)) < len(positions):
            first = next(p for i, p in enumerate(positions) if p in positions[:i])
            raise IngestError(
                path,
                f"the bag's index lists a chunk more than once ({len(positions):,} entries for "
                f"{len(set(positions)):,} chunks, the first repeated at byte {first:,}): damaged or tampered; "
                "`rosbag reindex` rebuilds it",
            )


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
    _check_magic(path)
    root = bag_root(path)
    _bound_decompression()
    # bags written without their message definitions (older ROS 2) fall back on the standard types
    default = get_typestore(Stores.ROS2_HUMBLE)
    try:
        reader = AnyReader([root], default_typestore=default)
        reader.open()
    except Exception as exc:
        raise IngestError(path, f"not a readable ROS bag: {type(exc).__name__}: {_one_line(exc)}") from None
    try:
        _check_index(path, reader)
    except IngestError:
        reader.close()
        raise

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
            raise IngestError(path, f"truncated or corrupt bag: {type(exc).__name__}: {_one_line(exc)}") from None

    def decoder_for(channel: _Channel, schema: _Schema) -> Callable[[bytes], object]:
        return lambda data: reader.deserialize(data, schema.name)

    try:
        parsed, reports = read_topics(path, options, feed=feed, decoder_for=decoder_for, fmt="bag")
    finally:
        reader.close()
    if on_bytes is not None:  # rosbags gives no byte position while reading: the whole file at the end
        on_bytes(path.stat().st_size)
    return parsed, reports
