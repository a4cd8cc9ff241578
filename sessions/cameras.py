"""Camera frames of a log in the session: one file of JPEGs and one index per camera, beside the log's array.

``logs/000007-cam0.frames`` holds the JPEGs back to back; ``logs/000007-cam0.idx`` is a NumPy array of
``(t, offset, size)`` records in time order, ``t`` in seconds since the log's first sample. The log's catalog row
names both (``info["cameras"]``); like the arrays they are data anyone could replace, so both are checked before
they are read.
"""

from __future__ import annotations

import io
import os
import shutil
import threading
import uuid
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import SessionError
from .ingest.image_topics import CameraStream
from .limits import MAX_STORED_FRAME_BYTES
from .log_files import checked_in_logs
from .logs import LogInfo

INDEX_DTYPE = np.dtype([("t", "<f8"), ("offset", "<i8"), ("size", "<i8")])
THUMB_PX = 112  # a thumbnail's width: the ground's texture at a glance, ~3 KB a picture in a table of twelve
THUMBS_KEPT = 256  # thumbnails kept in memory, newest first: a table redrawn at every keypress reads none again


@dataclass(frozen=True)
class CameraInfo:
    """A camera of a log: its topic, how many frames the session keeps, their size in pixels."""

    index: int
    topic: str
    frames: int
    width: int
    height: int


@dataclass(frozen=True)
class CameraFrame:
    """One kept frame: its time in seconds since the log's first sample, and its JPEG bytes."""

    t: float
    jpeg: bytes
    number: int  # 0-based, in time order
    of: int  # frames of the camera


def stage_cameras(logs_dir: Path, cameras: tuple[CameraStream, ...], *, t0: float) -> list[tuple[Path, Path, dict]]:
    """Write a log's frames and indexes to staged files in ``logs_dir`` (renamed into place with the log)."""
    staged = []
    for k, cam in enumerate(cameras):
        tag = uuid.uuid4().hex
        frames, index = logs_dir / f".tmp-{tag}.frames", logs_dir / f".tmp-{tag}.idx"
        staged.append((frames, index, {}))
        cam.data.seek(0)
        with open(frames, "wb") as out:
            shutil.copyfileobj(cam.data, out, 1 << 20)
            out.flush()
            os.fsync(out.fileno())
        records = np.empty(len(cam.times), INDEX_DTYPE)
        records["t"], records["offset"], records["size"] = cam.times - t0, cam.offsets, cam.sizes
        with open(index, "wb") as out:
            np.save(out, records, allow_pickle=False)
            out.flush()
            os.fsync(out.fileno())
        staged[-1][2].update(
            {"topic": cam.topic, "frames": len(records), "width": cam.width, "height": cam.height, "camera": k}
        )
        if cam.skipped[0]:  # frames that could not be read (damaged, over a limit): counted, with the first reason
            staged[-1][2].update({"skipped": cam.skipped[0], "skipped_why": cam.skipped[1]})
    return staged


def place_cameras(logs_dir: Path, log_id: int, staged: list[tuple[Path, Path, dict]]) -> tuple[list[dict], list[Path]]:
    """Rename staged camera files to the log's names; returns the catalog entries and the placed paths."""
    entries, placed = [], []
    for frames, index, meta in staged:
        stem = f"{log_id:06d}-cam{meta['camera']}"
        for src, suffix in ((frames, "frames"), (index, "idx")):
            dst = logs_dir / f"{stem}.{suffix}"
            os.replace(src, dst)
            placed.append(dst)
        entries.append({**meta, "file": f"{logs_dir.name}/{stem}.frames", "index": f"{logs_dir.name}/{stem}.idx"})
    return entries, placed


class CameraStore:
    """Camera frames for :class:`sessions.Session` (a mixin over its path and catalog)."""

    # Session's path and catalog, which this part uses
    path: Path
    log: Callable[[int], LogInfo]
    _camera_index: dict[tuple[int, int], tuple[np.ndarray, Path]]
    _camera_lock: threading.Lock
    _thumbs: OrderedDict[tuple[int, int, int, int], bytes]

    def cameras(self, log_id: int) -> list[CameraInfo]:
        """The cameras whose frames the session keeps for a log (none for CSV logs and logs without images)."""
        out = []
        for k, entry in enumerate(self.log(log_id).info.get("cameras", []) or []):  # type: ignore[union-attr]
            try:
                out.append(
                    CameraInfo(k, str(entry["topic"]), int(entry["frames"]), int(entry["width"]), int(entry["height"]))
                )
            except (KeyError, TypeError, ValueError):
                raise SessionError(f"{self.path}: log {log_id}: damaged camera entry in the catalog") from None
        return out

    def _index(self, log_id: int, camera: int) -> tuple[np.ndarray, Path]:
        key = (log_id, camera)
        with self._camera_lock:
            found = self._camera_index.get(key)
        if found is not None:
            return found
        entries = self.log(log_id).info.get("cameras", []) or []
        if not 0 <= camera < len(entries):  # type: ignore[arg-type]
            raise SessionError(f"{self.path}: log {log_id} has no camera {camera}")
        entry = entries[camera]  # type: ignore[index]
        what = f"log {log_id}'s camera {entry.get('topic', camera)!r}"
        name = str(self.path)
        frames, _ = checked_in_logs(self.path, str(entry.get("file", "")), name=name, what=f"{what} frames")
        index_path, _ = checked_in_logs(self.path, str(entry.get("index", "")), name=name, what=f"{what} index")
        try:
            index = np.load(index_path, allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise SessionError(f"{self.path}: {what} index is unreadable ({exc}); re-ingest the log") from None
        size = frames.stat().st_size
        ok = index.dtype == INDEX_DTYPE and index.ndim == 1
        if ok and len(index):
            offsets, sizes = index["offset"], index["size"]
            ok = offsets.min() >= 0 and sizes.min() >= 0 and sizes.max() <= MAX_STORED_FRAME_BYTES
            ok = ok and (offsets + sizes).max() <= size
        if not ok:
            raise SessionError(f"{self.path}: {what} index does not match its frames; the session was changed")
        with self._camera_lock:
            self._camera_index[key] = (index, frames)
        return index, frames

    def camera_times(self, log_id: int, camera: int = 0) -> np.ndarray:
        """``(N,)`` times of a camera's kept frames, seconds since the log's first sample."""
        return np.asarray(self._index(log_id, camera)[0]["t"])

    def camera_frame_number(self, log_id: int, seconds: float, *, camera: int = 0, within_s: float = 1.0) -> int | None:
        """The number of the kept frame nearest ``seconds`` into a log, or ``None`` when none is within
        ``within_s`` (a camera that started late or dropped out shows nothing, not a stale picture)."""
        t = self._index(log_id, camera)[0]["t"]
        if not len(t):
            return None
        j = int(np.searchsorted(t, seconds))
        i = min((k for k in (j - 1, j) if 0 <= k < len(t)), key=lambda k: abs(float(t[k]) - seconds))
        return None if abs(float(t[i]) - seconds) > within_s else i

    def camera_frame(
        self, log_id: int, seconds: float, *, camera: int = 0, within_s: float = 1.0
    ) -> CameraFrame | None:
        """The frame shown at ``seconds`` into a log (:meth:`camera_frame_number`), with its JPEG bytes."""
        i = self.camera_frame_number(log_id, seconds, camera=camera, within_s=within_s)
        return None if i is None else self._read_frame(log_id, camera, i)

    def _read_frame(self, log_id: int, camera: int, i: int) -> CameraFrame:
        index, frames = self._index(log_id, camera)
        with open(frames, "rb") as f:
            f.seek(int(index["offset"][i]))
            data = f.read(int(index["size"][i]))
        return CameraFrame(float(index["t"][i]), data, i, len(index))

    def camera_frames_between(self, log_id: int, start_s: float, stop_s: float, *, camera: int = 0) -> list[int]:
        """Numbers of a camera's kept frames in ``[start_s, stop_s)`` seconds into a log."""
        t = self.camera_times(log_id, camera)
        return list(range(int(np.searchsorted(t, start_s)), int(np.searchsorted(t, stop_s))))

    def camera_frame_by_number(self, log_id: int, number: int, *, camera: int = 0) -> CameraFrame:
        """A kept frame by its number (:meth:`camera_frames_between`), with its JPEG bytes."""
        return self._read_frame(log_id, camera, number)

    def camera_thumbnail(
        self, log_id: int, seconds: float, *, camera: int = 0, within_s: float = 1.0, width: int = THUMB_PX
    ) -> bytes | None:
        """A small JPEG of the frame nearest ``seconds`` into a log (``None`` when none is within ``within_s``),
        ``width`` pixels wide; the last :data:`THUMBS_KEPT` are kept in memory.

        Raises:
            SessionError: The camera's files are damaged, or a frame is no picture Pillow can read.
        """
        from PIL import Image

        i = self.camera_frame_number(log_id, seconds, camera=camera, within_s=within_s)
        if i is None:
            return None
        key = (log_id, camera, i, width)
        with self._camera_lock:
            if key in self._thumbs:
                self._thumbs.move_to_end(key)
                return self._thumbs[key]
        frame = self._read_frame(log_id, camera, i)
        try:
            with Image.open(io.BytesIO(frame.jpeg)) as picture:
                picture.draft("RGB", (width, width))  # JPEG: decode at 1/2, 1/4 or 1/8 scale, not whole
                small = picture.convert("RGB")
                small.thumbnail((width, 4 * width))
                out = io.BytesIO()
                small.save(out, "JPEG", quality=80)
        except (OSError, ValueError, Image.DecompressionBombError) as exc:
            raise SessionError(f"{self.path}: log {log_id}'s camera frame {i + 1} is unreadable ({exc})") from None
        with self._camera_lock:
            self._thumbs[key] = out.getvalue()
            while len(self._thumbs) > THUMBS_KEPT:
                self._thumbs.popitem(last=False)
        return out.getvalue()
