"""A synthetic downward camera for the demo walks: the ground under the robot, a texture per terrain, moving with the
walk, written as ``sensor_msgs/CompressedImage`` JPEGs.

The frame's middle row is the ground under the feet; rows above lie ahead, rows below behind, so a terrain change
slides through the picture as the robot walks over it, as a real downward camera shows it.
"""

from __future__ import annotations

import io

import numpy as np

from .walks import TERRAINS, Walk

CAMERA_FPS = 5.0
WIDTH, HEIGHT = 192, 144  # px
PX_PER_M = 240.0  # the frame shows 0.6 m of ground front to back
TILE = 256  # px, texture tile (repeats along the walk)
JPEG_QUALITY = 65

_BASE = {  # (colour, roughness) of each terrain's ground
    "concrete": ((150, 150, 146), 10.0),
    "grass": ((70, 130, 50), 35.0),
    "gravel": ((135, 125, 110), 45.0),
    "mulch": ((95, 60, 35), 30.0),
    "dirt": ((125, 90, 60), 15.0),
    "sand": ((215, 195, 140), 8.0),
}


def _blur(x: np.ndarray, n: int) -> np.ndarray:
    """Box blur of a periodic ``(H, W)`` field, ``n`` px, in both directions."""
    for axis in (0, 1):
        x = sum(np.roll(x, k, axis=axis) for k in range(-n, n + 1)) / (2 * n + 1)
    return x


def terrain_tile(terrain: str, seed: int = 0) -> np.ndarray:
    """A periodic ``(TILE, TILE, 3)`` uint8 ground texture of a terrain: what a person recognises it by."""
    rng = np.random.default_rng([seed, TERRAINS.index(terrain)])
    colour, rough = _BASE[terrain]
    fine = rng.normal(0, 1, (TILE, TILE))
    if terrain == "grass":  # blades: streaks along the walk
        field = _blur(fine, 1) + 1.5 * np.roll(_blur(rng.normal(0, 1, (TILE, TILE)), 2), 3, axis=0)
        field = np.where(field > 0.6, 1.6, field)
    elif terrain == "gravel":  # stones: bright blobs with dark gaps
        field = np.sign(_blur(fine, 3)) * 1.2 + 0.4 * fine
    elif terrain == "mulch":  # chips: elongated dark and light flakes
        field = np.clip(_blur(fine, 2) * 3.0, -1.5, 1.5) + 0.3 * fine
    elif terrain == "concrete":  # smooth with a joint line and a few cracks
        field = 0.4 * _blur(fine, 4) + 0.2 * fine
        field[:, TILE // 2 - 1 : TILE // 2 + 1] = -3.0
    elif terrain == "sand":  # fine grain with ripples across the walk
        rows = np.arange(TILE)[:, None]
        field = 0.8 * np.sin(2 * np.pi * rows / 21.3) + 0.5 * fine
    else:  # dirt: clods
        field = 1.2 * _blur(fine, 5) * 4 + 0.3 * fine
    tint = rng.uniform(0.96, 1.04, 3)
    img = np.asarray(colour, np.float64)[None, None, :] * tint + rough * field[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def ground_frames(walk: Walk, *, seed: int = 0, fps: float = CAMERA_FPS) -> tuple[np.ndarray, list[bytes]]:
    """The camera's stamps (absolute seconds) and JPEG frames over a walk.

    Returns:
        ``(N,)`` stamps and ``N`` JPEG byte strings.
    """
    from PIL import Image

    tiles = {k: terrain_tile(k, seed) for k in TERRAINS}
    frame_t = np.arange(0.0, walk.times[-1], 1.0 / fps)
    travelled = np.interp(frame_t, walk.times, walk.distance)  # m
    starts = np.array([a for a, _, _ in walk.truth])
    names = [k for _, _, k in walk.truth]
    rows_m = (HEIGHT / 2 - np.arange(HEIGHT)) / PX_PER_M  # + ahead (top), - behind (bottom)
    rng = np.random.default_rng(seed + 104729)
    frames = []
    for t, d in zip(frame_t, travelled, strict=True):
        ground = d + rows_m  # (H,) m along the walk
        when = np.interp(ground, walk.distance, walk.times)  # when the feet were (or will be) there
        patch = np.clip(np.searchsorted(starts, when, side="right") - 1, 0, len(names) - 1)
        y = np.round(ground * PX_PER_M).astype(np.int64) % TILE
        x0 = int(rng.integers(-2, 3)) + TILE // 2 - WIDTH // 2  # a little sideways wobble
        img = np.empty((HEIGHT, WIDTH, 3), np.uint8)
        for name in set(patch.tolist()):
            rows = np.nonzero(patch == name)[0]
            tile = tiles[names[name]]
            img[rows] = tile[y[rows]][:, (x0 + np.arange(WIDTH)) % TILE]
        shade = 1.0 + 0.04 * np.sin(2 * np.pi * 1.8 * t)  # the body's bob changes the light a little
        out = io.BytesIO()
        Image.fromarray(np.clip(img * shade, 0, 255).astype(np.uint8)).save(out, format="JPEG", quality=JPEG_QUALITY)
        frames.append(out.getvalue())
    return walk.t0 + frame_t, frames
