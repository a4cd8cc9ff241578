"""Each log's path on the ground coloured by its terrain: what the map in the export, the page and Foxglove draw.

A log's track is the best it has (a GNSS fix first: it lines up with every other run's; then odometry, a localiser's
pose, ``/tf``, a CSV's columns). At each pose the terrain is the person's label where there is one (full colour),
else the model's answer where it is sure (lighter), else unsure or unscored (grey). Tracks of one frame share their
axes (GNSS in local metres from the first fix of all the runs), so a terrain seen in two runs lines up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sessions import KNOWN_TERRAIN_COLORS, LogClock, LogInfo, PoseTrack, Segment, TerrainPath, local_metres

TRACK_ORDER = ("gnss", "odometry", "pose", "tf", "csv", "dead-reckoned")
SURE = 0.6  # the model's answer is drawn where its probability is at least this, else grey
MOST_POSES = 5000  # poses drawn of one log (decimated evenly past it, as the traces are)
LABEL, MODEL, UNSURE = 0, 1, 2  # what a pose's colour says
GREY = "#cfcfcf"  # unsure or unscored (lighter than concrete's #9e9e9e)
# a terrain without a session's colour (a bundle on files): its known colour, else the next of these
PALETTE = ("#1e88e5", "#e53935", "#8e24aa", "#00897b", "#fb8c00", "#3949ab", "#d81b60", "#00acc1")
ALPHA = {LABEL: 1.0, MODEL: 0.45}  # how strongly a source's colour is drawn (grey: GREY_ALPHA)
GREY_ALPHA = 0.7
# frames that stay put from run to run: tracks in them line up; any other (odom, a CSV's) starts again with each run
SHARED_FRAMES = ("wgs84", "map", "world", "earth", "utm")


@dataclass(frozen=True)
class LogPath:
    """One log's path as drawn.

    Attributes:
        log: The log's name.
        kind: The track's kind (``PoseTrack.kind``).
        frame: The frame its metres are in (``"wgs84"``: east and north metres from the shared first fix).
        times: ``(N,)`` seconds from the log's first sample.
        xy: ``(N, 2)`` metres.
        terrain: ``(N,)`` index into the session's terrains, ``-1`` where none is known.
        source: ``(N,)`` ``LABEL``, ``MODEL`` or ``UNSURE``.
        geo: ``(N, 3)`` latitude, longitude and altitude for a GNSS track, else ``None``.
    """

    log: str
    kind: str
    frame: str
    times: np.ndarray
    xy: np.ndarray
    terrain: np.ndarray
    source: np.ndarray
    geo: np.ndarray | None = None


def best_track(tracks: list[PoseTrack]) -> PoseTrack | None:
    """The track a log's path is drawn from: by :data:`TRACK_ORDER`, the longest of a kind."""
    ranked = [t for t in tracks if len(t.times) >= 2]
    if not ranked:
        return None
    return min(ranked, key=lambda t: (TRACK_ORDER.index(t.kind) if t.kind in TRACK_ORDER else 99, -len(t.times)))


def log_path(
    log: LogInfo | LogClock,
    track: PoseTrack,
    terrains: list[str],
    segments: list[Segment],
    *,
    probs: np.ndarray | None = None,
    classes: list[str] | None = None,
    origin: tuple[float, float] | None = None,
) -> LogPath:
    """``log``'s path from ``track`` with each pose's terrain: its label, else the model's sure answer (``probs``,
    ``(T, K)`` over ``classes``), else unsure. ``origin``: the latitude and longitude GNSS metres count from."""
    step = max(1, -(-len(track.times) // MOST_POSES))
    times, values = track.times[::step], track.values[::step]
    samples = np.clip(np.round(times * log.rate_hz).astype(np.int64), 0, max(0, log.n_samples - 1))  # (N,)
    terrain = np.full(len(times), -1, np.int64)
    source = np.full(len(times), UNSURE, np.int64)
    if probs is not None and classes is not None and len(probs):
        at = np.clip(samples, 0, len(probs) - 1)
        best, sure = probs[at].argmax(axis=1), probs[at].max(axis=1) >= SURE
        index = np.asarray([terrains.index(c) if c in terrains else -1 for c in classes], np.int64)
        named = sure & (index[best] >= 0)
        terrain[named], source[named] = index[best][named], MODEL
    for seg in segments:
        if seg.terrain in terrains:
            inside = (samples >= seg.start) & (samples < seg.stop)
            terrain[inside], source[inside] = terrains.index(seg.terrain), LABEL
    geo = None
    if track.geographic:
        geo = values[:, :3]
        xy = local_metres(values, origin or (float(values[0, 0]), float(values[0, 1])))
    else:
        xy = values[:, :2]
    return LogPath(log.name, track.kind, track.frame, times, xy, terrain, source, geo)


def panel_of(path: LogPath) -> str:
    """Which panel of a map ``path`` is drawn in: one per shared frame, else one of its own."""
    return path.frame if path.frame.lower() in SHARED_FRAMES else f"{path.log} (frame {path.frame})"


def first_fix(tracks: list[PoseTrack | None]) -> tuple[float, float] | None:
    """The first GNSS fix among ``tracks``: where every run's local metres start from."""
    fixes = [t for t in tracks if t is not None and t.geographic and len(t.times)]
    return None if not fixes else (float(fixes[0].values[0, 0]), float(fixes[0].values[0, 1]))


def stretches(path: LogPath) -> list[tuple[int, int, int, int]]:
    """The runs of poses of one terrain and one source: ``(first, last + 1, terrain, source)`` each; neighbouring
    runs share their boundary pose so the drawn path has no holes."""
    if len(path.times) == 0:
        return []
    key = path.terrain * 3 + path.source
    cuts = np.flatnonzero(np.diff(key)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [len(key)]])
    return [
        (int(a), min(int(b) + 1, len(key)), int(path.terrain[a]), int(path.source[a]))
        for a, b in zip(starts, ends, strict=True)
    ]


def colour_of(terrain: int, source: int, terrains: list[tuple[str, str]]) -> tuple[str, str, float]:
    """A pose's terrain name, colour and alpha as every map draws it (grey where no terrain is known)."""
    if terrain < 0 or source not in ALPHA:
        return "unsure", GREY, GREY_ALPHA
    return terrains[terrain][0], terrains[terrain][1], ALPHA[source]


def terrain_path(path: LogPath, terrains: list[tuple[str, str]]) -> TerrainPath:
    """``path`` as its terrain MCAP file carries it (``sessions.TerrainPath``), ``terrains`` each terrain's name
    and colour in the session's order."""
    xyz = np.column_stack([path.xy, np.zeros(len(path.xy))])  # (N, 3): the ground, in metres
    runs = tuple((a, b, *colour_of(t, s, terrains)) for a, b, t, s in stretches(path))
    return TerrainPath(path.frame, path.times, xyz, runs, path.geo)


def class_colours(classes: list[str] | tuple[str, ...]) -> list[tuple[str, str]]:
    """Each class with a colour where no session gives one (``classify`` on files): a known terrain's own, else the
    palette's next one not taken."""
    out, taken = [], set()
    for name in classes:
        colour = KNOWN_TERRAIN_COLORS.get(name.lower())
        if colour is None or colour in taken:
            colour = next((c for c in PALETTE if c not in taken), PALETTE[len(out) % len(PALETTE)])
        taken.add(colour)
        out.append((name, colour))
    return out
