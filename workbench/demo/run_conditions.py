"""What differs from one demo walk to the next and is not terrain: speed, gait, sensor gains, how the IMU is mounted.

A real robot's next run differs from its last in ways that have nothing to do with the ground: it walks faster, its
gait settles at another frequency, a force sensor was recalibrated, the IMU was remounted a few degrees off. A model
that learned the run instead of the terrain scores well on held-back pieces of its runs and worse on new ones; the
demo walks draw these per walk so that ``make test`` and the demo protocol exercise it, not only BorealTC.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RunConditions:
    """One walk's conditions.

    Attributes:
        speed: Scale of the walking speed.
        gait: Scale of the gait frequency at a given speed.
        imu_gain: Gains of the accelerometer's and the gyroscope's axes (x, y, z, then x, y, z).
        force_gain: Gain of each foot's force sensor (fl, fr, rl, rr).
        mount_rad: Roll and pitch of the IMU on the body.
    """

    speed: float = 1.0
    gait: float = 1.0
    imu_gain: tuple[float, ...] = (1.0,) * 6
    force_gain: tuple[float, ...] = (1.0,) * 4
    mount_rad: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def draw(cls, seed: int) -> RunConditions:
        """The conditions of walk ``seed``, from a stream of their own: its terrain patches stay the seed's."""
        rng = np.random.default_rng([seed, 0x52554E])
        return cls(
            speed=float(rng.uniform(0.8, 1.2)),
            gait=float(rng.uniform(0.9, 1.1)),
            imu_gain=tuple(float(g) for g in rng.uniform(0.97, 1.03, 6)),
            force_gain=tuple(float(g) for g in rng.uniform(0.9, 1.1, 4)),
            mount_rad=(float(rng.normal(0, np.radians(2.0))), float(rng.normal(0, np.radians(2.0)))),
        )

    def measure_imu(
        self, accel: np.ndarray, gyro: np.ndarray, quat: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The body's ``accel (T, 3)``, ``gyro (T, 3)`` and orientation ``quat (T, 4)`` (x, y, z, w) as the mounted
        IMU reports them: in its own frame, with its gains."""
        mount = _roll_pitch(*self.mount_rad)
        r = _matrix(mount)  # (3, 3) the IMU's axes in the body frame
        gains = np.asarray(self.imu_gain)
        return (accel @ r) * gains[:3], (gyro @ r) * gains[3:], _multiply(quat, mount)

    def measure_forces(self, forces: np.ndarray) -> np.ndarray:
        """Feet's ``forces (T, 4, 3)`` as their sensors report them."""
        return forces * np.asarray(self.force_gain)[None, :, None]


def _matrix(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _roll_pitch(roll: float, pitch: float) -> np.ndarray:
    """The quaternion (x, y, z, w) of a roll, then a pitch."""
    cr, sr, cp, sp = np.cos(roll / 2), np.sin(roll / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    return np.array([sr * cp, cr * sp, -sr * sp, cr * cp])


def _multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products ``a (T, 4) · b (4,)``, both (x, y, z, w)."""
    ax, ay, az, aw = a.T
    bx, by, bz, bw = b
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=1,
    )
