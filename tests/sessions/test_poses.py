"""Where the robot was: a log's positions read beside its signals, never among them, without impossible poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from sessions import IngestOptions, PoseTrack, Session, local_metres
from sessions.ingest.poses import clean


def _walk_csv(path: Path, *, n: int = 3000, rate: float = 50.0, geo: bool = False) -> pd.DataFrame:
    rng = np.random.default_rng(0)
    t = np.arange(n) / rate
    frame = pd.DataFrame({"time": t, "ax": rng.normal(size=n), "ay": rng.normal(size=n)})
    if geo:  # about 1 m/s north-east from a field near Sherbrooke
        frame["lat"] = 45.38 + t * 7e-6
        frame["lon"] = -71.92 + t * 1e-5
    else:
        frame["x"], frame["y"] = np.cos(t / 20) * 30, np.sin(t / 20) * 30  # a circle of 30 m at 1.5 m/s
    frame.to_csv(path, index=False)
    return frame


def test_a_csvs_position_columns_are_a_pose_track_and_not_signals(tmp_path: Path) -> None:
    frame = _walk_csv(tmp_path / "walk.csv")
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([tmp_path / "walk.csv"])
    assert [c.name for c in log.channels] == ["ax", "ay"]
    assert any("columns x, y read as the robot's position" in n for n in log.info["notes"])
    (track,) = s.poses(log.id)
    assert (track.kind, track.frame, track.dropped) == ("csv", "csv", 0)
    assert np.allclose(track.times, frame["time"]) and np.allclose(track.values[:, :2], frame[["x", "y"]])
    assert Session.open(tmp_path / "s").poses(log.id)[0].values.shape == (3000, 3)  # kept on disk


def test_a_phone_loggers_x_y_z_axes_stay_signals(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(2000) / 100.0
    pd.DataFrame(
        {"time": t, "x": rng.normal(size=2000), "y": rng.normal(size=2000), "z": 9.8 + rng.normal(size=2000)}
    ).to_csv(tmp_path / "Accelerometer.csv", index=False)
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([tmp_path / "Accelerometer.csv"])
    assert [c.name for c in log.channels] == ["x", "y", "z"] and s.poses(log.id) == []


def test_impossible_fixes_are_dropped_and_counted_in_one_note(tmp_path: Path) -> None:
    frame = _walk_csv(tmp_path / "gnss.csv", geo=True)
    frame.loc[10, "lat"] = np.nan
    frame.loc[20, "lat"] = 95.0
    frame.loc[30, ["lat", "lon"]] = (54.0, -61.9)  # 1,000 km away for one step
    frame.loc[40, "time"] = frame.loc[39, "time"]  # no time between two fixes
    frame.to_csv(tmp_path / "gnss.csv", index=False)
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([tmp_path / "gnss.csv"], options=IngestOptions(allow_gaps=True))
    (track,) = s.poses(log.id)
    assert track.kind == "gnss" and track.geographic and track.dropped == 4 and len(track.times) == 2996
    notes = [n for n in log.info["notes"] if "positions dropped" in n]
    assert notes == [
        "columns lat, lon read as the robot's position (a pose track), not as signals; 4 of 3,000 "
        "positions dropped as impossible (not finite, out of range or a jump)"
    ]


def test_one_wild_pose_first_does_not_take_the_track_with_it() -> None:
    t = np.arange(100, dtype=np.float64)
    xyz = np.column_stack([t * 0.5, np.zeros(100), np.zeros(100)])
    xyz[0] = (1e6, 0, 0)
    track = clean(PoseTrack("odometry", "/odom", "odom", t, xyz))
    assert track.dropped == 1 and track.times[0] == 1.0 and len(track.times) == 99


def test_fixes_in_local_metres_from_the_first() -> None:
    east_north = local_metres(np.array([[45.0, -71.0], [45.001, -71.0], [45.0, -70.999]]), (45.0, -71.0))
    assert np.allclose(east_north[1], (0.0, 111.19), atol=0.01)
    assert np.allclose(east_north[2], (78.63, 0.0), atol=0.01)


def test_an_mcaps_odometry_tf_and_a_drivers_own_gnss_message_give_three_tracks(tmp_path: Path) -> None:
    from tests.sessions.mcap_fixtures import path_at, write_with_poses

    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([write_with_poses(tmp_path / "drive.mcap")])
    assert all(c.name.startswith("imu/") for c in log.channels)  # positions never become signals
    tracks = {t.kind: t for t in s.poses(log.id)}
    assert set(tracks) == {"odometry", "tf", "gnss"}
    odom, tf, fix = tracks["odometry"], tracks["tf"], tracks["gnss"]
    assert (odom.source, odom.frame, len(odom.times)) == ("/odom", "odom", 80)
    assert (tf.source, tf.frame) == ("/tf:base_link", "odom")  # the robot's base, not the camera beside it
    x, y = path_at(odom.times[40])
    assert np.allclose(odom.values[40, :2], (x, y)) and np.allclose(tf.values[:, :2], odom.values[:, :2])
    assert fix.frame == "wgs84" and len(fix.times) == 20 and np.allclose(fix.values[:, 2], 250.0)
    assert odom.times[0] == 0.0  # seconds from the log's first sample


def test_wild_fixes_are_dropped_and_named_in_one_note(tmp_path: Path) -> None:
    from tests.sessions.mcap_fixtures import write_with_poses

    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([write_with_poses(tmp_path / "drive.mcap", wild_fix=True)])
    (fix,) = [t for t in s.poses(log.id) if t.kind == "gnss"]
    assert fix.dropped == 2 and len(fix.times) == 18
    assert [n for n in log.info["notes"] if "dropped as impossible" in n] == [
        "positions of /gnss/fix: 2 of 20 dropped as impossible (not finite, time going back, out of range or a jump)"
    ]


def test_a_small_robots_odometry_is_its_signals_by_a_mapping_and_its_path_from_the_same_log(tmp_path: Path) -> None:
    import pytest

    from sessions import ChannelSpec, IngestError, Mapping
    from tests.sessions.mcap_fixtures import write_with_poses

    drive = write_with_poses(tmp_path / "small.mcap", small_robot=True)
    s = Session.create(tmp_path / "s")
    with pytest.raises(IngestError, match="no usable sensor channel"):  # no sensor, rightly refused
        s.ingest([drive])
    twist = tuple(ChannelSpec("/odom", f"twist.twist.{a}") for a in ("linear.x", "angular.z"))
    (log,) = s.ingest([drive], options=IngestOptions(mapping=Mapping(channels=twist)))
    assert [c.name for c in log.channels] == ["odom/twist.twist.linear.x", "odom/twist.twist.angular.z"]
    tracks = {t.source: t for t in s.poses(log.id)}
    assert set(tracks) == {"/odom", "/tf:base_link", "/amcl_pose"}
    assert tracks["/amcl_pose"].frame == "map" and len(tracks["/amcl_pose"].times) == 8
