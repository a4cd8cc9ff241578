"""Vectorised CDR encoding of fixed-layout ROS 2 messages, for writing long synthetic logs fast.

mcap-ros2-support's writer encodes one message per Python call; the demo writes millions, so each message type
here is a NumPy structured dtype laid out exactly as CDR (little endian, fields aligned to their size relative to
the end of the 4-byte encapsulation header). The ingest tests decode these with mcap-ros2-support itself, so a
layout mistake cannot pass unnoticed.
"""

from __future__ import annotations

import struct

import numpy as np

SEP = "=" * 80
HEADER_DEFS = f"""{SEP}
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
{SEP}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec"""
VECTOR3 = f"""{SEP}
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z"""

IMU_SCHEMA = f"""std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
{HEADER_DEFS}
{SEP}
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
{VECTOR3}
"""

WRENCH_STAMPED_SCHEMA = f"""std_msgs/Header header
geometry_msgs/Wrench wrench
{HEADER_DEFS}
{SEP}
MSG: geometry_msgs/Wrench
geometry_msgs/Vector3 force
geometry_msgs/Vector3 torque
{VECTOR3}
"""


COMPRESSED_IMAGE_SCHEMA = f"""std_msgs/Header header
string format
uint8[] data
{HEADER_DEFS}
"""


def compressed_image(stamp: float, frame_id: str, fmt: str, data: bytes) -> bytes:
    """CDR bytes of one sensor_msgs/CompressedImage (variable length: encoded one at a time, they are few)."""
    body = bytearray()

    def pad4() -> None:  # alignment counts from after the encapsulation header
        body.extend(b"\0" * (-len(body) % 4))

    sec = int(np.floor(stamp))
    body += struct.pack("<iI", sec, min(round((stamp - sec) * 1e9), 999_999_999))
    for text in (frame_id, fmt):
        raw = text.encode() + b"\0"
        pad4()
        body += struct.pack("<I", len(raw)) + raw
    pad4()
    body += struct.pack("<I", len(data)) + data
    return b"\x00\x01\x00\x00" + bytes(body)


def _header_dtype(frame_id: str, n_floats: int) -> tuple[np.dtype, int]:
    """Encapsulation + std_msgs/Header, then ``n_floats`` float64 at the next 8-aligned offset."""
    name = frame_id.encode() + b"\0"
    end = 4 + 12 + len(name)  # encapsulation, sec, nanosec, string length, string bytes
    first = 4 + ((end - 4 + 7) // 8) * 8  # alignment counts from after the encapsulation header
    dtype = np.dtype(
        {
            "names": ["enc", "sec", "nanosec", "strlen", "frame", "values"],
            "formats": ["<u4", "<i4", "<u4", "<u4", f"S{len(name)}", ("<f8", (n_floats,))],
            "offsets": [0, 4, 8, 12, 16, first],
            "itemsize": first + 8 * n_floats,
        }
    )
    return dtype, len(name)


def encode(stamps: np.ndarray, values: np.ndarray, frame_id: str) -> tuple[bytes, int]:
    """CDR bytes of ``N`` messages that are a header followed by float64s only.

    Args:
        stamps: ``(N,)`` float64 absolute seconds.
        values: ``(N, K)`` the message's float64 fields in declaration order (covariances included).
        frame_id: The header's frame id.

    Returns:
        One buffer of ``N`` records and the size of each record.
    """
    dtype, strlen = _header_dtype(frame_id, values.shape[1])
    out = np.zeros(len(stamps), dtype=dtype)
    out["enc"] = 0x00000100  # bytes 00 01 00 00: CDR, little endian
    sec = np.floor(stamps)
    out["sec"] = sec.astype(np.int32)
    out["nanosec"] = np.minimum(np.round((stamps - sec) * 1e9), 999_999_999).astype(np.uint32)
    out["strlen"] = strlen
    out["frame"] = frame_id.encode()
    out["values"] = values
    return out.tobytes(), dtype.itemsize


def imu_values(quat: np.ndarray, gyro: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """``(N, 37)`` float64 fields of sensor_msgs/Imu with zero covariances (``quat`` is x, y, z, w)."""
    n = len(quat)
    z = np.zeros((n, 9))
    return np.concatenate([quat, z, gyro, z, accel, z], axis=1)


def wrench_values(force: np.ndarray, torque: np.ndarray | None = None) -> np.ndarray:
    """``(N, 6)`` float64 fields of geometry_msgs/Wrench."""
    return np.concatenate([force, np.zeros_like(force) if torque is None else torque], axis=1)


def _strings_then_floats(stamp: float, strings: tuple[str, ...], floats: np.ndarray) -> bytearray:
    """A header's stamp, strings (the header's frame id first) and float64s at the next 8-aligned offset."""
    body = bytearray()
    sec = int(np.floor(stamp))
    body += struct.pack("<iI", sec, min(round((stamp - sec) * 1e9), 999_999_999))
    for text in strings:
        raw = text.encode() + b"\0"
        body.extend(b"\0" * (-len(body) % 4))
        body += struct.pack("<I", len(raw)) + raw
    body.extend(b"\0" * (-len(body) % 8))
    body += np.asarray(floats, "<f8").tobytes()
    return body


def odometry(stamp: float, xy: tuple[float, float], yaw: float, speed: float, turn: float) -> bytes:
    """CDR bytes of one nav_msgs/Odometry in ``odom`` for ``base_link`` (zero covariances)."""
    quat = (0.0, 0.0, float(np.sin(yaw / 2)), float(np.cos(yaw / 2)))
    floats = np.concatenate([[xy[0], xy[1], 0.0], quat, np.zeros(36), [speed, 0, 0, 0, 0, turn], np.zeros(36)])
    return b"\x00\x01\x00\x00" + bytes(_strings_then_floats(stamp, ("odom", "base_link"), floats))


def navsatfix(stamp: float, lat: float, lon: float, alt: float, *, sigma_m: float) -> bytes:
    """CDR bytes of one sensor_msgs/NavSatFix (status: a fix from GPS; a diagonal covariance of ``sigma_m``)."""
    body = bytearray()
    sec = int(np.floor(stamp))
    body += struct.pack("<iI", sec, min(round((stamp - sec) * 1e9), 999_999_999))
    raw = b"gnss\0"
    body += struct.pack("<I", len(raw)) + raw
    body += struct.pack("<b", 0)  # status: STATUS_FIX
    body.extend(b"\0" * (-len(body) % 2))
    body += struct.pack("<H", 1)  # service: SERVICE_GPS
    body.extend(b"\0" * (-len(body) % 8))
    cov = np.diag([sigma_m**2, sigma_m**2, (2 * sigma_m) ** 2]).ravel()
    body += np.asarray([lat, lon, alt, *cov], "<f8").tobytes()
    body += struct.pack("<B", 2)  # COVARIANCE_TYPE_DIAGONAL_KNOWN
    return b"\x00\x01\x00\x00" + bytes(body)
