"""A log's pose tracks in its session: one ``NNNNNN-poseK.track`` (an ``.npy`` array) per track, listed in its info.

Each file is an ``(N, 4)`` float64 array: seconds from the log's first sample, then x, y, z in metres (or latitude,
longitude and altitude for a GNSS track). Staged with the log and renamed into place in the transaction that
records it, as camera frames are (``cameras.py``).
"""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .ingest.poses import PoseTrack
from .logs import LogInfo


def stage_poses(logs_dir: Path, tracks: tuple[PoseTrack, ...], *, t0: float) -> list[tuple[Path, dict]]:
    """Write a log's pose tracks to staged files in ``logs_dir``; each with its catalog entry so far."""
    staged = []
    for k, track in enumerate(t for t in tracks if len(t.times)):
        tmp = logs_dir / f".tmp-{uuid.uuid4().hex}.npy"
        rows = np.column_stack([track.times - t0, track.values])  # (N, 4)
        with open(tmp, "wb") as out:
            np.save(out, rows, allow_pickle=False)
            out.flush()
            os.fsync(out.fileno())
        meta = {"kind": track.kind, "source": track.source, "frame": track.frame, "poses": len(rows), "track": k}
        if track.dropped:
            meta["dropped"] = track.dropped
        staged.append((tmp, meta))
    return staged


def place_poses(logs_dir: Path, log_id: int, staged: list[tuple[Path, dict]]) -> tuple[list[dict], list[Path]]:
    """Rename staged pose files to the log's names; the catalog entries and the placed paths."""
    entries, placed = [], []
    for tmp, meta in staged:
        dst = logs_dir / f"{log_id:06d}-pose{meta['track']}.track"
        os.replace(tmp, dst)
        placed.append(dst)
        entries.append({**meta, "file": f"{logs_dir.name}/{dst.name}"})
    return entries, placed


class PoseStore:
    """Pose tracks for :class:`sessions.Session` (a mixin over its path and catalog)."""

    path: Path
    log: Callable[[int], LogInfo]

    def poses(self, log_id: int) -> list[PoseTrack]:
        """Where the robot was during a log: its tracks, times in seconds from the log's first sample (none for
        a log read without positions)."""
        out = []
        for entry in self.log(log_id).info.get("poses", []) or []:
            rows = np.load(self.path / str(entry["file"]), allow_pickle=False)  # (N, 4)
            out.append(
                PoseTrack(
                    str(entry["kind"]),
                    str(entry["source"]),
                    str(entry["frame"]),
                    rows[:, 0].copy(),
                    rows[:, 1:4].copy(),
                    int(entry.get("dropped", 0)),
                )
            )
        return out
