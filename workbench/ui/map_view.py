"""The map: viser's 3D scene seen from above, the log's path on the ground coloured by terrain, a marker at the
cursor, and a click on the ground moving the cursor to the nearest pose.

The scene shows either the robot at the cursor or the map (**M**, or the button above the traces): the page has one
3D canvas, and from above it is the map. The map takes the canvas's room from the traces panel while it is shown,
and gives it back. Colours are the export's (:mod:`workbench.maps`): a label full colour, the model's sure answer
lighter, unsure or unscored grey. The other logs of the same shared frame (GNSS, a ``map`` frame) are drawn thinner
under it so a terrain seen in two runs lines up; a log whose frame restarts with each run (``odom``) is drawn alone.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..maps import LABEL, MODEL, LogPath, best_track, colour_of, first_fix, log_path, panel_of

if TYPE_CHECKING:
    from sessions import LogInfo, Segment, Session

    from .host import PanelHost

OTHERS = 20  # other logs of the shared frame drawn under the log on screen, at most
OTHER_POSES = 1000  # poses of each of them, decimated evenly
TRACES_WIDTH, MAP_TRACES_WIDTH = 960, 560  # the traces panel with the robot, and with the map beside it
MODEL_ALPHA = 0.7  # the model's sure answer: lighter than a label, still its terrain's colour
PIXELS = {"other": 1.5, "path": 3.0, "label": 7.0}  # line widths on screen: other runs, the log's path, its labels


def _rgb(colour: str, alpha: float) -> np.ndarray:
    """A hex colour drawn at ``alpha`` over the white ground, as the bytes the page's lines take: three.js reads a
    line's vertex colours as linear light and brightens them for the screen, so they are sent darkened by the
    inverse (else every terrain reads as a pale grey)."""
    c = np.asarray([int(colour[i : i + 2], 16) for i in (1, 3, 5)], np.float64) / 255
    shown = 1 - alpha * (1 - c)  # over white, as on screen
    return np.round(255 * shown**2.2).astype(np.uint8)


def segment_colours(path: LogPath, terrains: list[tuple[str, str]]) -> np.ndarray:
    """``(N - 1, 2, 3)`` uint8: each segment of ``path`` in its first pose's colour (both ends alike), the model's
    answer at :data:`MODEL_ALPHA` (a thin line on a screen needs more colour than the picture's)."""
    each = []
    for t, s in zip(path.terrain, path.source, strict=True):
        _, colour, alpha = colour_of(int(t), int(s), terrains)
        each.append(_rgb(colour, MODEL_ALPHA if s == MODEL else alpha))
    return np.repeat(np.stack(each)[:-1, None, :], 2, axis=1)  # (N, 3) -> (N - 1, 2, 3)


def nearest_pose(xy: np.ndarray, point: tuple[float, float]) -> int:
    """Index of the pose of ``xy`` ``(N, 2)`` nearest ``point``."""
    return int(np.argmin(((xy - np.asarray(point)) ** 2).sum(axis=1)))


def ground_point(origin: tuple[float, float, float], direction: tuple[float, float, float]) -> tuple[float, float]:
    """Where a click's ray meets the ground (``z = 0``); straight below its origin for a ray parallel to it."""
    o, d = np.asarray(origin, np.float64), np.asarray(direction, np.float64)
    if abs(d[2]) < 1e-9 or -o[2] / d[2] < 0:
        return float(o[0]), float(o[1])
    at = o + d * (-o[2] / d[2])
    return float(at[0]), float(at[1])


def map_paths(session: Session, scores, log: LogInfo, segments: list[Segment]) -> tuple[LogPath | None, list[LogPath]]:
    """``log``'s path coloured by ``segments`` and by ``scores`` (the page's ``SessionScores``), and the paths of the
    other logs drawn with it: those of the same shared frame (GNSS, a ``map`` frame), at most :data:`OTHERS`, each
    decimated to :data:`OTHER_POSES`."""
    names = [t.name for t in session.terrains()]
    logs = session.logs()
    tracks = {x.id: best_track(session.poses(x.id)) for x in logs}
    origin = first_fix(list(tracks.values()))

    def path(x: LogInfo, own: list[Segment]) -> LogPath | None:
        track = tracks.get(x.id)
        if track is None:
            return None
        s = scores.scores.get(x.id)
        probs = None if s is None or s.probs is None else s.probs  # (T, K) over scores.classes
        return log_path(x, track, names, own, probs=probs, classes=list(scores.classes), origin=origin)

    mine = path(log, segments)
    if mine is None:
        return None, []
    shared, others = panel_of(mine) == mine.frame, []  # a frame that stays put from run to run
    for x in logs:
        if shared and x.id != log.id and len(others) < OTHERS and tracks.get(x.id) is not None:
            other = path(x, session.segments(x.id))
            if other is not None and other.frame == mine.frame:
                step = max(1, -(-len(other.times) // OTHER_POSES))
                cut = (other.times, other.xy, other.terrain, other.source)
                others.append(LogPath(other.log, other.kind, other.frame, *(a[::step] for a in cut)))
    return mine, others


def map_bounds(mine: LogPath, others: list[LogPath]) -> tuple[np.ndarray, np.ndarray]:
    """The lower left and upper right corners (metres) of the paths drawn; the map is centred between them."""
    every = np.concatenate([p.xy for p in [mine, *others]])  # (N, 2)
    return every.min(axis=0), every.max(axis=0)


class MapView:
    """One browser's map: built on first show and whenever the log, its labels or the scores change."""

    def __init__(self, host: PanelHost, *, robot_nodes: list) -> None:
        self.host = host
        self.shown = False
        self._robot_nodes = robot_nodes  # hidden while the map is shown
        self._key: tuple | None = None
        self._path: LogPath | None = None
        self._centre = np.zeros(2)  # the map's metres are drawn about this point (a GNSS path is far from 0)
        self._nodes: list = []
        self._marker = None
        self._framed: tuple | None = None  # (log id, extent) the camera was last placed for
        self._robot_camera: tuple | None = None  # position and look-at of the robot's view
        host.client.scene.on_click()(self._clicked)

    def has_positions(self, log: LogInfo) -> bool:
        """Whether ``log`` has a track to draw."""
        return best_track(self.host.state.session.poses(log.id)) is not None

    def toggle(self) -> bool:
        """Show the map, or the robot again; whether the map is shown."""
        self.shown = not self.shown
        for node in self._robot_nodes:
            node.visible = not self.shown
        for node in [*self._nodes, *([self._marker] if self._marker is not None else [])]:
            node.visible = self.shown
        self._framed = None
        camera = self.host.client.camera
        if self.shown:  # the robot's view, to give back
            self._robot_camera = (camera.position, camera.look_at)
        elif self._robot_camera is not None:
            camera.position, camera.look_at = self._robot_camera[:2]  # the position first, as in _draw
        self.update()
        return self.shown

    def update(self) -> None:
        """Draw the log on screen's path (again where it changed) and the marker at the cursor."""
        log = self.host.log
        if not self.shown or log is None:
            return
        session = self.host.state.session
        segments = session.segments(log.id)
        scores = self.host.state.scores
        key = (log.id, id(scores), tuple((g.start, g.stop, g.terrain) for g in segments), len(session.terrains()))
        if key != self._key:
            self._key = key
            self._draw(log, segments)
        if self._path is None:
            return
        j = int(np.clip(np.searchsorted(self._path.times, self.host.cursor_s), 0, len(self._path.times) - 1))
        x, y = self._path.xy[j] - self._centre
        self._marker.position = (float(x), float(y), 0.0)

    def _draw(self, log: LogInfo, segments) -> None:
        scene = self.host.client.scene
        for node in [*self._nodes, *([self._marker] if self._marker is not None else [])]:
            node.remove()
        self._nodes, self._marker = [], None
        mine, others = map_paths(self.host.state.session, self.host.state.scores, log, segments)
        self._path = mine
        if mine is None or len(mine.times) < 2:
            self._nodes.append(
                scene.add_label("/map/none", f"{log.name}: no positions in this log", position=(0, 0, 0))
            )
            return
        terrains = [(t.name, t.color) for t in self.host.state.session.terrains()]
        lo, hi = map_bounds(mine, others)
        self._centre = (lo + hi) / 2
        extent = float(max(hi[0] - lo[0], hi[1] - lo[1], 1.0))
        for k, p in enumerate([*others, mine]):
            xyz = np.column_stack([p.xy - self._centre, np.zeros(len(p.xy))])  # (N, 3) on the ground
            points = np.stack([xyz[:-1], xyz[1:]], axis=1).astype(np.float32)  # (N - 1, 2, 3)
            colours = segment_colours(p, terrains)
            layers = [("path" if p is mine else "other", np.ones(len(points), bool))]
            if p is mine:  # the person's labels drawn again, wider, over the model's answer
                layers.append(("label", p.source[:-1] == LABEL))
            for layer, keep in layers:
                if keep.any():
                    self._nodes.append(
                        scene.add_line_segments(
                            f"/map/{layer}{k}",
                            points[keep],
                            colours[keep],
                            thickness=PIXELS[layer],
                            thickness_units="screen",
                        )
                    )
        self._nodes += self._scale_and_north(mine, lo - self._centre, extent)
        self._marker = scene.add_icosphere("/map/marker", radius=extent * 0.012, color=(33, 33, 33))
        if self._framed != (log.id, extent):
            self._framed = (log.id, extent)
            camera = self.host.client.camera
            # from above and a little south, the scene's up kept: north (or the frame's +y) up the screen. The
            # position first: the page moves the camera's target with it, so the target is set after
            camera.position = (0.0, -extent * 0.25, extent * 1.6)
            camera.look_at = (0.0, 0.0, 0.0)

    def _scale_and_north(self, path: LogPath, corner: np.ndarray, extent: float) -> list:
        """A scale bar of a round length and the north (or +y) arrow at the map's lower left."""
        scene = self.host.client.scene
        bar = float(10 ** np.floor(np.log10(extent / 4)))  # 1, 10, 100 m ...
        bar *= 5 if 5 * bar <= extent / 3 else 2 if 2 * bar <= extent / 3 else 1
        x0, y0 = float(corner[0]), float(corner[1]) - extent * 0.06
        ink = (33, 33, 33)
        pts = np.asarray([[[x0, y0, 0], [x0 + bar, y0, 0]], [[x0, y0, 0], [x0, y0 + extent * 0.08, 0]]], np.float32)
        north = "N" if path.frame == "wgs84" else f"+y ({path.frame})"
        return [
            scene.add_line_segments("/map/scale", pts, ink, thickness=2.0, thickness_units="screen"),
            scene.add_label("/map/scale/len", f"{bar:g} m", position=(x0 + bar / 2, y0 - extent * 0.02, 0)),
            scene.add_label("/map/scale/north", north, position=(x0, y0 + extent * 0.1, 0)),
        ]

    def _clicked(self, event) -> None:
        """A click on the ground moves the cursor to the nearest pose of the log on screen."""
        if not self.shown or self._path is None:
            return
        x, y = ground_point(event.ray_origin, event.ray_direction)
        j = nearest_pose(self._path.xy - self._centre, (x, y))
        seconds = float(self._path.times[j])
        self.host.guard(lambda: self.host.move_cursor(seconds))
