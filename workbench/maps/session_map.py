"""The paths of a session's logs gathered as they are scored, then drawn: the export's ``terrain-map.png``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sessions import LogInfo, Session, TerrainPath

from .map_picture import write_map_picture
from .terrain_paths import LABEL, MODEL, LogPath, best_track, first_fix, log_path, terrain_path

MAP_FILE = "terrain-map.png"


class TerrainMap:
    """Each log's path with its terrains: :meth:`add` a log's scores as the export reads them (only the poses'
    rows are kept, so an hour of scores costs a few thousand rows), :meth:`write` the picture at the end; a log
    never scored is drawn with its labels alone."""

    def __init__(self, session: Session, logs: list[LogInfo]) -> None:
        self.session = session
        self.logs = logs
        self.tracks = {x.id: best_track(session.poses(x.id)) for x in logs}
        self.origin = first_fix(list(self.tracks.values()))
        self.terrains = session.terrains()
        self.paths: dict[int, LogPath] = {}

    def add(self, log: LogInfo, probs: np.ndarray | None, classes: list[str]) -> None:
        """Colour ``log``'s path by its labels and by ``probs`` (``(T, K)`` over ``classes``)."""
        track = self.tracks.get(log.id)
        if track is not None:
            self.paths[log.id] = self._path(log, track, probs, list(classes))

    def drawn(self, log: LogInfo) -> TerrainPath | None:
        """``log``'s path as its terrain MCAP file carries it (labels alone until :meth:`add` gave its scores)."""
        if log.id not in self.paths and (track := self.tracks.get(log.id)) is not None:
            self.paths[log.id] = self._path(log, track, None, None)
        path = self.paths.get(log.id)
        return None if path is None else terrain_path(path, [(t.name, t.color) for t in self.terrains])

    def write(self, out: Path) -> Path | None:
        """The picture at ``out`` (``None``, nothing written, when no log has positions)."""
        for log in self.logs:
            if log.id not in self.paths and (track := self.tracks.get(log.id)) is not None:
                self.paths[log.id] = self._path(log, track, None, None)
        drawn = [self.paths[x.id] for x in self.logs if x.id in self.paths]
        return write_map_picture(drawn, [(t.name, t.color) for t in self.terrains], out)

    def words(self) -> str:
        """What the picture shows, in a line."""
        drawn = list(self.paths.values())
        poses = sum(len(p.times) for p in drawn)
        labelled = sum(int((p.source == LABEL).sum()) for p in drawn)
        answered = sum(int((p.source == MODEL).sum()) for p in drawn)
        kinds = ", ".join(sorted({p.kind for p in drawn}))
        return (
            f"{len(drawn)} of {len(self.logs)} logs have positions ({kinds}); of the {poses:,} poses drawn, "
            f"{labelled / max(poses, 1):.0%} labelled, {answered / max(poses, 1):.0%} the model's sure answer, the "
            "rest grey (unsure or unscored)"
        )

    def _path(self, log: LogInfo, track, probs, classes) -> LogPath:
        names = [t.name for t in self.terrains]
        segments = self.session.segments(log.id)
        return log_path(log, track, names, segments, probs=probs, classes=classes, origin=self.origin)
