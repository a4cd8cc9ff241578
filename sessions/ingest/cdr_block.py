"""ROS 2 messages that are a header and then float64 fields only (``sensor_msgs/Imu``, ``geometry_msgs/WrenchStamped``,
``Vector3Stamped``...), decoded a block at a time with NumPy instead of one Python call per message.

mcap-ros2-support decodes each message field by field in Python: reading an hour of a quadruped's IMU and feet (1.08 M
messages) spent 7.7 s of 13.8 there and 2.3 s more picking fields out of the objects. A CDR message of this shape is
the encapsulation header, the stamp, the frame id (a length and its bytes), padding to 8 bytes, and the floats at
fixed offsets, so a block of them is one array view. Anything this module does not recognise (another layout,
big-endian CDR, a length that does not add up, a frame id without its terminating zero) is left to the library's
decoder, message by message, so what is read never depends on which path read it.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

CDR_LE = b"\x00\x01"  # encapsulation kind: plain CDR, little endian
_PRIMITIVES = {
    "bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
    "float32", "string", "wstring",
}  # fmt: skip
_FIELD = re.compile(r"^\s*([\w/]+(?:\[[^\]]*\])?)\s+(\w+)")
_TYPE = re.compile(r"([\w/]+)(?:\[(\d*)\])?")


def _fields(text: str) -> list[tuple[str, str]]:
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0]
        m = _FIELD.match(line)
        if m and "=" not in line.split(m.group(2), 1)[1][:2]:  # "TYPE NAME=VALUE" is a constant
            out.append((m.group(1), m.group(2)))
    return out


def float64_fields(schema: str) -> dict[tuple[str | int, ...], int] | None:
    """Where each float of a ``ros2msg`` schema lies when the message is a ``std_msgs/Header`` then float64 fields,
    nested messages and fixed arrays of them only: ``{field path: index}``; ``None`` for any other shape."""
    sections = re.split(r"^=+\s*$", schema, flags=re.M)
    defs: dict[str, str] = {}
    for section in sections[1:]:
        head, _, body = section.strip().partition("\n")
        m = re.match(r"MSG:\s*(\S+)", head)
        if m is None:
            return None
        name = m.group(1)
        defs[name] = defs[name.replace("/msg/", "/")] = defs[name.rsplit("/", 1)[-1]] = body
    main = _fields(sections[0])
    header = _fields(defs.get("std_msgs/Header", ""))
    stamp = _fields(defs.get("builtin_interfaces/Time", ""))
    if (
        not main
        or main[0][1] != "header"
        or main[0][0] not in ("std_msgs/Header", "Header")
        or [f[1] for f in header] != ["stamp", "frame_id"]
        or header[1][0] != "string"
        or stamp != [("int32", "sec"), ("uint32", "nanosec")]
    ):
        return None
    paths: list[tuple[str | int, ...]] = []

    def expand(fields: list[tuple[str, str]], prefix: tuple, depth: int) -> bool:
        for kind, name in fields:
            m = _TYPE.fullmatch(kind)
            if m is None or depth > 8:
                return False
            base, count = m.group(1), m.group(2)
            if count == "":  # a sequence: its length varies
                return False
            items = [(*prefix, name)] if count is None else [(*prefix, name, i) for i in range(int(count))]
            if base == "float64":
                paths.extend(items)
            elif base in _PRIMITIVES or base not in defs:
                return False
            else:
                for item in items:
                    if not expand(_fields(defs[base]), item, depth + 1):
                        return False
        return True

    if not expand(main[1:], (), 0) or not paths:
        return None
    return {p: i for i, p in enumerate(paths)}


def decode_block(datas: Sequence[bytes], n_floats: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A block of such messages: ``(N,)`` header stamps in seconds (NaN where zero: the log time is used then),
    ``(N, n_floats)`` float64 values, and ``(N,)`` whether each message had the expected layout (the others'
    rows are garbage and must be decoded one by one)."""
    n = len(datas)
    stamps = np.full(n, np.nan)
    values = np.zeros((n, n_floats))
    ok = np.zeros(n, bool)
    lengths = np.fromiter((len(d) for d in datas), np.int64, n)
    for length in np.unique(lengths):
        rows = np.flatnonzero(lengths == length)
        if length < 16:
            continue
        block = np.frombuffer(b"".join(datas[i] for i in rows), np.uint8).reshape(len(rows), int(length))
        strlen = block[:, 12:16].copy().view("<u4")[:, 0].astype(np.int64)
        first = 4 + ((12 + strlen + 7) // 8) * 8  # the floats start 8-aligned after the encapsulation header
        good = (block[:, 0] == 0) & (block[:, 1] == 1) & (strlen >= 1) & (first + 8 * n_floats == length)
        for start in np.unique(first[good]):
            sel = np.flatnonzero(good & (first == start))
            zero = block[sel, 16 + strlen[sel] - 1] == 0  # the frame id ends with its terminating zero
            sel = sel[zero]
            if not len(sel):
                continue
            sec = block[sel, 4:8].copy().view("<i4")[:, 0].astype(np.float64)
            nsec = block[sel, 8:12].copy().view("<u4")[:, 0].astype(np.float64)
            t = sec + nsec * 1e-9
            stamps[rows[sel]] = np.where(t > 0, t, np.nan)
            values[rows[sel]] = block[sel, start : start + 8 * n_floats].copy().view("<f8")
            ok[rows[sel]] = True
    return stamps, values, ok
