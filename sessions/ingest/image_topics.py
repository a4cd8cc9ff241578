"""Camera frames read beside the sensor streams: kept as JPEG with their stamps, never in the float arrays.

A person judges terrain by looking at the ground, so ingest keeps a log's ``sensor_msgs/Image`` and
``sensor_msgs/CompressedImage`` topics as pictures. Disk stays bounded: at most ``IngestOptions.camera_fps``
frames a second are kept (chosen by the message's log time, so frames that are dropped are never decoded), JPEGs up
to ``MAX_SIDE`` pixels are kept as recorded, and larger ones, raw and PNG images are encoded as JPEG no larger than
that. A 1080p camera then costs, estimated at about 30 KB a 640 px frame, 60 KB a second (200 MB an hour). Depth images
are no view of the ground a person can judge: they are left out.
"""

from __future__ import annotations

import io
import tempfile
from dataclasses import dataclass
from typing import IO

import numpy as np

from ..limits import MAX_FRAME_PIXELS
from .fields import get, stamp_seconds

CAMERA_TYPES = ("sensor_msgs/Image", "sensor_msgs/CompressedImage")
MAX_SIDE = 640  # px: the longest side of a kept frame
JPEG_QUALITY = 80
_CHANNELS = {"rgb8": 3, "bgr8": 3, "rgba8": 4, "bgra8": 4, "mono8": 1, "8uc1": 1, "8uc3": 3, "mono16": 1, "16uc1": 1}


def is_camera(schema: str) -> bool:
    """A ROS 2 (``pkg/msg/Type``) or ROS 1 (``pkg/Type``) image message type."""
    return schema.replace("/msg/", "/") in CAMERA_TYPES


@dataclass(frozen=True)
class CameraStream:
    """The kept frames of one image topic.

    Attributes:
        topic: The topic.
        times: ``(N,)`` float64 stamps in seconds, on the sensor streams' clock, ascending.
        offsets: ``(N,)`` byte offset of each JPEG in ``data``.
        sizes: ``(N,)`` bytes of each JPEG.
        data: A temporary file holding the JPEGs (deleted when closed).
        width: Width of the first frame, px.
        height: Height of the first frame, px.
        skipped: Frames that could not be read (an unsupported encoding, a damaged image), with the first reason.
    """

    topic: str
    times: np.ndarray
    offsets: np.ndarray
    sizes: np.ndarray
    data: IO[bytes]
    width: int
    height: int
    skipped: tuple[int, str] = (0, "")


def _jpeg(image, *, quality: int = JPEG_QUALITY) -> bytes:
    if max(image.size) > MAX_SIDE:
        scale = MAX_SIDE / max(image.size)
        image = image.resize((max(1, round(image.width * scale)), max(1, round(image.height * scale))))
    if image.mode not in ("RGB", "L"):
        image = image.convert("RGB")
    out = io.BytesIO()
    image.save(out, format="JPEG", quality=quality)
    return out.getvalue()


def _raw_image(msg: object):
    from PIL import Image

    encoding = str(get(msg, ("encoding",))).lower()
    channels = _CHANNELS.get(encoding)
    if channels is None:
        raise ValueError(f"image encoding {encoding!r} is not supported (rgb8, bgr8, rgba8, bgra8, mono8, mono16 are)")
    height, width, step = (int(get(msg, (k,))) for k in ("height", "width", "step"))
    _check_pixels(width, height)
    wide = encoding in ("mono16", "16uc1")
    raw = np.frombuffer(bytes(get(msg, ("data",))), np.uint8)
    if step < width * channels * (2 if wide else 1) or raw.size < step * height:
        raise ValueError(f"image data of {raw.size} bytes does not hold {height} rows of {step} bytes")
    rows = raw[: step * height].reshape(height, step)
    if wide:  # 16-bit grey: scaled to 8 bits over its own range, for a person to look at
        order = ">u2" if int(get(msg, ("is_bigendian",)) or 0) else "<u2"
        pixels = rows[:, : width * 2].copy().view(order).reshape(height, width).astype(np.float32)
        lo, hi = float(pixels.min()), float(pixels.max())
        arr = ((pixels - lo) * (255.0 / max(hi - lo, 1.0))).astype(np.uint8)
    else:
        arr = rows[:, : width * channels].reshape(height, width, channels)
        if encoding.startswith("bgr"):
            arr = arr[..., [2, 1, 0, *([3] if channels == 4 else [])]]
        if channels == 1:
            arr = arr[..., 0]
    return Image.fromarray(np.ascontiguousarray(arr))


def _check_pixels(width: int, height: int) -> None:
    """Refuse a frame whose declared size is over ``MAX_FRAME_PIXELS``, before anything is decoded."""
    if width * height > MAX_FRAME_PIXELS:
        raise ValueError(
            f"a frame of {width:,} x {height:,} pixels, over the limit of {MAX_FRAME_PIXELS:,} pixels "
            "(sessions/limits.py)"
        )


def frame_jpeg(msg: object, schema: str) -> tuple[bytes, int, int]:
    """The JPEG of one image message and its ``(width, height)``.

    Raises:
        ValueError: A depth image, an unsupported encoding or damaged image data.
    """
    from PIL import Image, UnidentifiedImageError

    if schema.replace("/msg/", "/") == "sensor_msgs/CompressedImage":
        fmt = str(get(msg, ("format",))).lower()
        if "compresseddepth" in fmt:
            raise ValueError("a compressed depth image")
        data = bytes(get(msg, ("data",)))
        try:
            image = Image.open(io.BytesIO(data))  # reads the header only: the size is known before decoding
        except Image.DecompressionBombError as exc:  # Pillow's own guard, past ours: the frame, not the log
            raise ValueError(f"a frame over the limit of {MAX_FRAME_PIXELS:,} pixels (Pillow: {exc})") from None
        except UnidentifiedImageError:  # its message names the BytesIO object it read from
            raise ValueError(f"image data is no picture ({fmt or 'no format'}: no image format recognised)") from None
        except (OSError, ValueError) as exc:
            raise ValueError(f"image data is no picture ({fmt or 'no format'}: {exc})") from None
        _check_pixels(*image.size)
        if image.format == "JPEG" and max(image.size) <= MAX_SIDE:
            return data, *image.size  # as recorded
        try:
            image.load()
        except (OSError, ValueError) as exc:
            raise ValueError(f"image data is no picture ({fmt or 'no format'}: {exc})") from None
    else:
        image = _raw_image(msg)
    out = _jpeg(image)
    return out, *Image.open(io.BytesIO(out)).size


class CameraCollector:
    """Frames of one image topic as they are read: at most ``fps`` a second, JPEG bytes spilled to a temporary file.

    Args:
        topic: The topic.
        schema: Its message type.
        fps: Most frames kept a second (by message log time).
    """

    def __init__(self, topic: str, schema: str, *, fps: float) -> None:
        self.topic, self.schema = topic, schema
        self._period_ns = round(1e9 / fps)
        self._last_slot: int | None = None  # frames are kept one per slot of 1 / fps seconds of log time
        self._times: list[float] = []
        self._sizes: list[int] = []
        self._file: IO[bytes] | None = None
        self._size = (0, 0)
        self._skipped = 0
        self._why = ""

    def wants(self, log_time_ns: int) -> bool:
        """Whether the message logged at ``log_time_ns`` is kept (decided before it is decoded)."""
        return self._last_slot is None or log_time_ns // self._period_ns > self._last_slot

    def skip(self, why: str) -> None:
        """Count a frame that cannot be read (the next one is tried at once)."""
        self._skipped += 1
        self._why = self._why or why

    def add(self, msg: object, log_time_ns: int) -> None:
        """Keep a decoded image message; one that cannot be read is counted and skipped, never an error."""
        try:
            jpeg, width, height = frame_jpeg(msg, self.schema)
        except (ValueError, TypeError, AttributeError, KeyError, IndexError) as exc:
            self.skip(str(exc))
            return
        self._last_slot = log_time_ns // self._period_ns
        if self._file is None:
            self._file = tempfile.TemporaryFile(prefix="workbench-camera-")  # noqa: SIM115 (lives with the frames)
            self._size = (width, height)
        stamp = stamp_seconds(msg, ())  # the header's, as for sensor rows; else the log time
        self._times.append(stamp if stamp is not None else log_time_ns * 1e-9)
        self._sizes.append(len(jpeg))
        self._file.write(jpeg)

    def result(self) -> CameraStream | None:
        """The kept frames in stamp order, or ``None`` when none could be read."""
        if self._file is None:
            return None
        self._file.flush()
        sizes = np.asarray(self._sizes, np.int64)
        offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64)
        times = np.asarray(self._times, np.float64)
        order = np.argsort(times, kind="stable")
        return CameraStream(
            self.topic,
            times[order],
            offsets[order],
            sizes[order],
            self._file,
            *self._size,
            skipped=(self._skipped, self._why),
        )

    @property
    def note(self) -> str:
        """What the dry run says of the topic."""
        kept = f"camera: {len(self._times)} frames kept (at most {1e9 / self._period_ns:g} a second)"
        return kept + (f"; {self._skipped} unreadable ({self._why})" if self._skipped else "")
