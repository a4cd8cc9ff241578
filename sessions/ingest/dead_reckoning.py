"""A path dead-reckoned from wheel speeds and a yaw rate, for a log that records no position of its own.

A wheeled robot's motor log (BorealTC's Husky: ``velL, velR`` in m/s at 6.5 Hz) and its IMU's yaw rate (``wz`` in
rad/s at 100 Hz) are enough to draw where it went: the heading is the yaw rate integrated on the IMU's clock, the
speed the mean of the wheels', and each step of the wheels' clock moves the robot that far along the heading of the
time. It drifts (a gyro's bias turns it, a skidding wheel stretches it) and it restarts at the origin with each
run, so its kind and frame say ``dead-reckoned`` wherever it is drawn, and it never lines up with another run's.
Positions never become signals: the track is kept beside the log, as every other track is.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .base import Stream
from .poses import PoseTrack

KIND = FRAME = "dead-reckoned"
LEFT = ("vell", "vel_left", "left_vel", "left_velocity", "wheel_left", "left_wheel_speed", "speed_left")
RIGHT = ("velr", "vel_right", "right_vel", "right_velocity", "wheel_right", "right_wheel_speed", "speed_right")
YAW_RATE = ("wz", "gz", "gyro_z", "angular_velocity.z", "gyro.z", "yaw_rate")


def _find(streams: Sequence[Stream], names: Sequence[str]) -> tuple[Stream, int] | None:
    """The stream and column whose channel's last part is one of ``names`` (case ignored)."""
    for stream in streams:
        for k, channel in enumerate(stream.channels):
            last = channel.lower().split("/")[-1]
            if last in names:
                return stream, k
    return None


def _column(stream: Stream, k: int, *, block: int = 1 << 16) -> np.ndarray:
    """Column ``k`` of ``stream``'s values, read a block of rows at a time where they are on disk (an hour of a
    22-channel IMU is 60 MB a channel less than its rows)."""
    values = stream.values
    if isinstance(values, np.ndarray):
        return np.asarray(values[:, k], np.float64)
    n = len(values)
    return np.concatenate([values[a : min(a + block, n), [k]][:, 0] for a in range(0, n, block)] or [np.zeros(0)])


def dead_reckoned(streams: Sequence[Stream]) -> PoseTrack | None:
    """The path of a log's wheel speeds and yaw rate, or ``None`` when it lacks either (or has too little of them).

    The wheels' left and right speeds must be in one stream (one clock); the yaw rate may be in another, read at
    its own rate for the heading."""
    left, right, yaw = _find(streams, LEFT), _find(streams, RIGHT), _find(streams, YAW_RATE)
    if left is None or right is None or yaw is None or left[0] is not right[0]:
        return None
    wheels, gyro = left[0], yaw[0]
    t = np.asarray(wheels.times, np.float64)  # (N,)
    tg = np.asarray(gyro.times, np.float64)  # (M,)
    if len(t) < 2 or len(tg) < 2:
        return None
    rows = np.column_stack([_column(wheels, left[1]), _column(wheels, right[1])])  # (N, 2)
    rate = _column(gyro, yaw[1])  # (M,)
    ok, okg = np.isfinite(rows).all(axis=1), np.isfinite(rate)
    t, rows, tg, rate = t[ok], rows[ok], tg[okg], rate[okg]
    if len(t) < 2 or len(tg) < 2:
        return None
    # the heading at the gyro's samples (trapezoids), read at the wheels' times
    heading = np.concatenate([[0.0], np.cumsum(np.diff(tg) * (rate[1:] + rate[:-1]) / 2)])  # (M,)
    theta = np.interp(t, tg, heading)  # (N,)
    speed = rows.mean(axis=1)  # (N,) m/s
    dt = np.diff(t)  # (N - 1,)
    mid = (theta[1:] + theta[:-1]) / 2
    step = (speed[1:] + speed[:-1]) / 2 * dt
    xy = np.vstack([[0.0, 0.0], np.cumsum(np.column_stack([step * np.cos(mid), step * np.sin(mid)]), axis=0)])
    source = f"{wheels.channels[left[1]]},{wheels.channels[right[1]]} + {gyro.channels[yaw[1]]}"
    return PoseTrack(KIND, source, FRAME, t, np.column_stack([xy, np.zeros(len(t))]))
