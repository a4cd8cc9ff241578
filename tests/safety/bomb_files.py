"""Small files that decode to a lot: the bomb corpus of ``test_bombs``, written without ever holding what they
decode to (zstd and lz4 compress 1 MB of zeros at a time)."""

from __future__ import annotations

import io
import struct
from pathlib import Path

from mcap.data_stream import RecordBuilder
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Schema
from mcap_ros2.writer import Writer
from PIL import Image

from tests.sessions.mcap_fixtures import header, imu_msg
from workbench.demo import COMPRESSED_IMAGE_SCHEMA, IMU_SCHEMA

MAGIC = b"\x89MCAP0\r\n"
MiB = 1 << 20


def _message_prefix(length: int, sequence: int, log_time: int) -> bytes:
    """A Message record's opcode, length and fixed fields, for ``length`` bytes of data on channel 1."""
    return struct.pack("<BQHIQQ", 0x05, 2 + 4 + 8 + 8 + length, 1, sequence, log_time, log_time)


def _zeros(total: int):
    for start in range(0, total, MiB):
        yield bytes(min(MiB, total - start))


def _compressed_messages(compression: str, messages: int, size: int) -> tuple[bytes, int]:
    """``messages`` Imu messages of ``size`` zero bytes each, compressed as one chunk's records; their decoded size."""
    parts = []
    for i in range(messages):
        parts.append(_message_prefix(size, i, 1_000_000_000 + i))
        parts.extend(_zeros(size))
    decoded = messages * (len(_message_prefix(size, 0, 0)) + size)
    if compression == "zstd":
        import zstandard

        out = io.BytesIO()
        with zstandard.ZstdCompressor(level=3).stream_writer(out, size=decoded, closefd=False) as w:
            for p in parts:
                w.write(p)
        return out.getvalue(), decoded
    import lz4.frame

    c = lz4.frame.LZ4FrameCompressor()
    out = [c.begin()] + [c.compress(p) for p in parts] + [c.flush()]
    return b"".join(out), decoded


def chunk_bomb(path: Path, *, compression: str = "zstd", messages: int = 4, size: int = 400_000_000,
               declared: int | None = None) -> Path:  # fmt: skip
    """An MCAP whose one chunk decodes to ``messages × size`` bytes of ``sensor_msgs/Imu`` messages of zeros; the chunk
    declares ``declared`` decoded bytes (default: the truth). No index: readers walk it front to back."""
    data, decoded = _compressed_messages(compression, messages, size)
    b = RecordBuilder()
    Header(profile="ros2", library="bomb").write(b)
    Schema(id=1, name="sensor_msgs/msg/Imu", encoding="ros2msg", data=IMU_SCHEMA.encode()).write(b)
    Channel(id=1, schema_id=1, topic="/imu", message_encoding="cdr", metadata={}).write(b)
    Chunk(
        compression=compression,
        data=data,
        message_start_time=1_000_000_000,
        message_end_time=1_000_000_000 + messages,
        uncompressed_crc=0,
        uncompressed_size=decoded if declared is None else declared,
    ).write(b)
    DataEnd(data_section_crc=0).write(b)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(b)
    path.write_bytes(MAGIC + b.end() + MAGIC)
    return path


def png_bomb(width: int = 30_000, height: int = 30_000) -> bytes:
    """A PNG whose header declares ``width × height`` pixels: a real header, rows of zeros compressed (~50 KB)."""
    import zlib

    small = io.BytesIO()
    Image.new("L", (8, 8)).save(small, format="PNG")
    png = bytearray(small.getvalue())
    at = png.index(b"IHDR")
    png[at + 4 : at + 12] = struct.pack(">II", width, height)
    png[at + 17 : at + 21] = struct.pack(">I", zlib.crc32(bytes(png[at : at + 17])))  # the IHDR's CRC again
    idat = zlib.compress(bytes(width + 1) * 50, 9)  # the first rows only: enough to look like a picture
    end = png.index(b"IEND") - 4
    chunk = struct.pack(">I", len(idat)) + b"IDAT" + idat + struct.pack(">I", zlib.crc32(b"IDAT" + idat))
    return bytes(png[: png.index(b"IDAT") - 4]) + chunk + bytes(png[end:])


def jpeg_bomb(width: int = 30_000, height: int = 30_000) -> bytes:
    """A JPEG whose frame header (SOF0) declares ``width × height`` pixels."""
    small = io.BytesIO()
    Image.new("RGB", (16, 16), (90, 140, 60)).save(small, format="JPEG")
    jpeg = bytearray(small.getvalue())
    at = jpeg.index(b"\xff\xc0")
    jpeg[at + 5 : at + 9] = struct.pack(">HH", height, width)
    return bytes(jpeg)


def camera_log(path: Path, hostile: bytes, *, fmt: str = "png", seconds: float = 3.0) -> Path:
    """An IMU at 100 Hz and a camera at 5 Hz whose first frame is ``hostile``; the other frames are small JPEGs."""
    good = io.BytesIO()
    Image.new("RGB", (64, 48), (120, 110, 90)).save(good, format="JPEG")
    with open(path, "wb") as f:
        w = Writer(f)
        imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU_SCHEMA)
        cam = w.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED_IMAGE_SCHEMA)
        for i in range(int(seconds * 100)):
            t = 100.0 + i / 100
            ns = round(t * 1e9)
            w.write_message("/imu", imu, imu_msg(t, i), log_time=ns, publish_time=ns)
            if i % 20 == 0:
                frame = i // 20
                data, f_fmt = (hostile, fmt) if frame == 0 else (good.getvalue(), "jpeg")
                m = {"header": header(t, "cam"), "format": f_fmt, "data": data}
                w.write_message("/camera/compressed", cam, m, log_time=ns, publish_time=ns)
        w.finish()
    return path


def _ros1_records(raw: bytes, start: int) -> list[tuple[int, int, dict[str, bytes], bytes]]:
    """``(offset, end, header fields, data)`` of every record of a ROS 1 bag from ``start``."""
    records, pos = [], start
    while pos < len(raw):
        (hlen,) = struct.unpack_from("<I", raw, pos)
        fields, at = {}, pos + 4
        while at < pos + 4 + hlen:
            (flen,) = struct.unpack_from("<I", raw, at)
            name, _, value = raw[at + 4 : at + 4 + flen].partition(b"=")
            fields[name.decode()] = value
            at += 4 + flen
        (dlen,) = struct.unpack_from("<I", raw, at)
        records.append((pos, at + 4 + dlen, fields, raw[at + 4 : at + 4 + dlen]))
        pos = at + 4 + dlen
    return records


def _ros1_record(fields: dict[str, bytes], data: bytes) -> bytes:
    header = b"".join(struct.pack("<I", len(k) + 1 + len(v)) + k.encode() + b"=" + v for k, v in fields.items())
    return struct.pack("<I", len(header)) + header + struct.pack("<I", len(data)) + data


def ros1_chunk_bomb(path: Path, *, zeros: int = 300_000_000) -> Path:
    """A ROS 1 bag whose bz2 chunk holds its messages and ``zeros`` bytes after them: a few hundred bytes more on
    disk, ``zeros`` more when decoded. Written by ``rosbags``, then the chunk record rebuilt and the index moved."""
    import bz2

    from rosbags.rosbag1 import Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    from tests.sessions.test_ingest_bag import _write

    small = path.with_name(path.stem + "-small.bag")
    ts = get_typestore(Stores.ROS1_NOETIC)
    writer = BagWriter(small)
    writer.set_compression(BagWriter.CompressionFormat.BZ2)  # before it opens
    with writer as w:
        _write(w, ts.serialize_ros1, ts, 0.5)
    raw = small.read_bytes()
    magic = raw.index(b"\n") + 1
    (head, *rest) = _ros1_records(raw, magic)
    start, end, fields, data = next(r for r in rest if r[2]["op"] == b"\x05")  # the one chunk
    c = bz2.BZ2Compressor(9)
    parts = [c.compress(bz2.decompress(data))] + [c.compress(z) for z in _zeros(zeros)] + [c.flush()]
    decoded = len(bz2.decompress(data)) + zeros
    chunk = _ros1_record({**fields, "size": struct.pack("<I", decoded)}, b"".join(parts))
    delta = len(chunk) - (end - start)
    h_start, h_end, h_fields, h_data = head
    (index_pos,) = struct.unpack("<Q", h_fields["index_pos"])
    header = _ros1_record({**h_fields, "index_pos": struct.pack("<Q", index_pos + delta)}, h_data)
    assert len(header) == h_end - h_start  # the bag header keeps its padded size
    path.write_bytes(raw[:magic] + header + raw[h_end:start] + chunk + raw[end:])
    small.unlink()
    return path


def ros1_count_lie(path: Path, *, field: str = "chunk_count", value: int = 0xFFFFFFFF) -> Path:
    """A ROS 1 bag whose header claims ``value`` for ``field`` (``chunk_count``, ``conn_count``): the index read
    from the file must stop where the file does."""
    from rosbags.rosbag1 import Writer as BagWriter
    from rosbags.typesys import Stores, get_typestore

    from tests.sessions.test_ingest_bag import _write

    ts = get_typestore(Stores.ROS1_NOETIC)
    with BagWriter(path) as w:
        _write(w, ts.serialize_ros1, ts, 0.5)
    raw = path.read_bytes()
    magic = raw.index(b"\n") + 1
    h_start, h_end, h_fields, h_data = _ros1_records(raw, magic)[0]
    header = _ros1_record({**h_fields, field: struct.pack("<I", value)}, h_data)
    assert len(header) == h_end - h_start
    path.write_bytes(raw[:magic] + header + raw[h_end:])
    return path


def ros2_message_bomb(folder: Path, *, zeros: int = 300_000_000) -> Path:
    """A ROS 2 SQLite bag with zstd-compressed messages, one of which is ``zeros`` bytes of zeros compressed (a few
    KB in the database). Returns the ``.db3``."""
    import sqlite3

    import zstandard
    from rosbags.rosbag2 import Writer as Bag2Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    from tests.sessions.test_ingest_bag import _write

    ts = get_typestore(Stores.ROS2_HUMBLE)
    writer = Bag2Writer(folder, version=8)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    with writer as w:
        _write(w, ts.serialize_cdr, ts, 0.5)
    db3 = next(folder.glob("*.db3"))
    out = io.BytesIO()
    with zstandard.ZstdCompressor(level=3).stream_writer(out, size=zeros, closefd=False) as z:
        for block in _zeros(zeros):
            z.write(block)
    with sqlite3.connect(db3) as conn:
        conn.execute("UPDATE messages SET data = ? WHERE id = (SELECT MIN(id) FROM messages)", (out.getvalue(),))
    return db3
