"""The robot view: viser's 3D scene shows the body turning with the IMU orientation and the four foot-force
vectors at the cursor time; Space plays the log back with the traces."""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .host import PanelHost

BODY = (0.6, 0.3, 0.12)  # m, a small quadruped's trunk
FEET = {"fl": (0.27, 0.14), "fr": (0.27, -0.14), "rl": (-0.27, 0.14), "rr": (-0.27, -0.14)}
LEG = 0.3  # m, body height above the feet
N_PER_M = 250.0  # force arrow scale: 250 N draws 1 m
PLAY_FPS = 12.0


def _channel(names: tuple[str, ...], *needles: str) -> int | None:
    for i, n in enumerate(names):
        if all(x in n for x in needles):
            return i
    return None


def _quat_wxyz(x: float, y: float, z: float, w: float) -> tuple[float, float, float, float]:
    q = np.array([w, x, y, z], np.float64)
    norm = np.linalg.norm(q)
    return tuple(q / norm) if norm > 1e-6 else (1.0, 0.0, 0.0, 0.0)  # type: ignore[return-value]


def _rotate(wxyz: tuple[float, float, float, float], v: np.ndarray) -> np.ndarray:
    w, x, y, z = wxyz
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return v @ r.T


class RobotView:
    def __init__(self, host: PanelHost) -> None:
        self.host = host
        scene = host.client.scene
        scene.set_up_direction("+z")
        self.ground = scene.add_grid("/ground", 3.0, 3.0, cell_size=0.25, position=(0.0, 0.0, 0.0))
        self.body = scene.add_box("/robot/body", color=(90, 110, 100), dimensions=BODY, position=(0, 0, LEG))
        self.head = scene.add_box(
            "/robot/body/head", color=(46, 125, 50), dimensions=(0.06, 0.12, 0.08), position=(BODY[0] / 2, 0, 0)
        )
        self.forces = scene.add_line_segments(
            "/robot/forces", np.zeros((4, 2, 3), np.float32), (211, 47, 47), thickness=0.02
        )
        self._playing = threading.Event()
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._play, daemon=True)
        self._thread.start()

    def update(self) -> None:
        log = self.host.log
        if log is None:
            return
        names = log.channel_names
        i = min(log.sample_at(self.host.cursor_s), log.n_samples - 1)
        row = np.asarray(self.host.state.session.array(log.id)[i], np.float64)
        q = [_channel(names, "orientation", f".{a}") for a in "xyzw"]
        wxyz = _quat_wxyz(*(row[k] for k in q)) if None not in q else (1.0, 0.0, 0.0, 0.0)  # type: ignore[misc]
        self.body.wxyz = wxyz
        segs = np.zeros((4, 2, 3), np.float32)
        for j, (foot, (fx, fy)) in enumerate(FEET.items()):
            hip = _rotate(wxyz, np.array([fx, fy, -BODY[2] / 2])) + np.array([0, 0, LEG])
            toe = np.array([hip[0], hip[1], 0.0])
            f = [_channel(names, foot, "force", f".{a}") for a in "xyz"]
            vec = np.array([row[k] if k is not None else 0.0 for k in f]) / N_PER_M
            segs[j, 0], segs[j, 1] = toe, toe + vec
        self.forces.points = segs

    def toggle_play(self) -> None:
        if self._playing.is_set():
            self._playing.clear()
        else:
            self._playing.set()

    def _play(self) -> None:
        last = time.monotonic()
        while not self._closed.is_set():
            if not self._playing.wait(0.5):
                last = time.monotonic()
                continue
            time.sleep(1.0 / PLAY_FPS)
            if self._closed.is_set():  # close() wakes the loop to end it
                return
            now = time.monotonic()
            log = self.host.log
            if log is None:
                continue
            t = self.host.cursor_s + (now - last)
            last = now
            if t >= log.duration_s:
                self._playing.clear()
                t = log.duration_s
            self.host.guard(lambda t=t: self.host.move_cursor(t))

    def close(self) -> None:
        self._closed.set()
        self._playing.set()
