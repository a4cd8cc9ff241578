"""A wheeled robot's path dead-reckoned from its wheel speeds and yaw rate where it records no position."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sessions import Session
from sessions.ingest.base import Stream
from sessions.ingest.dead_reckoning import dead_reckoned
from tests.conftest import shared_data


def _streams(speed: float, yaw_rate: float, seconds: float, *, spin: bool = False) -> list[Stream]:
    """Wheels at 6.5 Hz (left, right) and a gyro at 100 Hz, as BorealTC's Husky records them."""
    tw, tg = np.arange(0, seconds, 1 / 6.5), np.arange(0, seconds, 0.01)
    left = np.full(len(tw), -speed if spin else speed)
    wheels = np.column_stack([np.ones(len(tw)), left, np.full(len(tw), speed)])
    gyro = np.column_stack([np.zeros(len(tg)), np.full(len(tg), yaw_rate)])
    return [
        Stream("pro", tw, wheels, ("pro/curL", "pro/velL", "pro/velR"), ("A", "m/s", "m/s"), ("a", "b", "c")),
        Stream("imu", tg, gyro, ("imu/wx", "imu/wz"), ("rad/s", "rad/s"), ("d", "e")),
    ]


def test_a_straight_drive_a_circle_and_a_spin_in_place() -> None:
    straight = dead_reckoned(_streams(1.0, 0.0, 10.0))
    assert straight is not None and (straight.kind, straight.frame) == ("dead-reckoned", "dead-reckoned")
    assert np.allclose(straight.values[-1], (straight.times[-1], 0.0, 0.0), atol=1e-9)  # 1 m/s east from 0
    circle = dead_reckoned(_streams(1.0, 0.1, 2 * np.pi / 0.1 + 0.01))  # one turn of radius 10 m
    assert circle is not None
    far = np.hypot(*circle.values[:, :2].T)
    assert abs(far.max() - 20.0) < 0.1 and far[-1] < 0.2  # across the circle's diameter, and back where it began
    spin = dead_reckoned(_streams(0.5, 0.8, 10.0, spin=True))  # skid steer turning in place
    assert spin is not None and np.abs(spin.values).max() < 1e-12
    assert dead_reckoned(_streams(1.0, 0.0, 10.0)[:1]) is None  # no yaw rate: no path


def test_a_csv_with_wheel_speeds_and_a_yaw_rate_gets_a_dead_reckoned_track_its_channels_kept(tmp_path) -> None:
    t = np.arange(0, 30, 0.02)
    pd.DataFrame({"time": t, "velL": 0.5, "velR": 0.5, "wz": 0.0, "az": 9.8}).to_csv(
        tmp_path / "husky.csv", index=False
    )
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([tmp_path / "husky.csv"])
    assert log.channel_names == ("velL", "velR", "wz", "az")  # the signals stay signals
    (track,) = s.poses(log.id)
    assert track.kind == "dead-reckoned" and np.allclose(track.values[-1, :2], (0.5 * t[-1], 0.0), atol=1e-6)
    s.close()


def test_a_borealtc_run_has_a_dead_reckoned_path_as_long_as_its_wheels_drove(tmp_path: Path) -> None:
    folder = shared_data("borealtc", "ASPHALT")
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([folder / "imu_01.csv", folder / "pro_01.csv"])
    (track,) = s.poses(log.id)
    wheels = pd.read_csv(folder / "pro_01.csv")
    driven = float(np.trapezoid((wheels.velL + wheels.velR) / 2, wheels.time))
    travelled = float(np.hypot(*np.diff(track.values[:, :2], axis=0).T).sum())
    assert track.kind == "dead-reckoned" and abs(travelled - abs(driven)) < 0.02 * abs(driven)
    s.close()
