"""ROS 1 bags and ROS 2 SQLite bags, written by ``rosbags`` itself, read through the same topics as MCAP."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sessions import IngestError, Session

RATE = 100.0


def _messages(ts):
    """Types and builders of an IMU and a foot wrench from a rosbags type store."""
    t = ts.types
    header = t["std_msgs/msg/Header"]
    stamp = t["builtin_interfaces/msg/Time"]
    vec, quat = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Quaternion"]

    def hdr(sec: float, frame: str, seq: int):
        whole = int(sec)
        kw = {"seq": seq} if "seq" in header.__dataclass_fields__ else {}
        return header(**kw, stamp=stamp(sec=whole, nanosec=round((sec - whole) * 1e9)), frame_id=frame)

    def imu(sec: float, i: int):
        return t["sensor_msgs/msg/Imu"](
            hdr(sec, "imu", i),
            quat(0.0, 0.0, float(np.sin(i / 50)), float(np.cos(i / 50))),
            np.zeros(9),
            vec(0.1 * i, -0.2 * i, 0.3),
            np.zeros(9),
            vec(1.0, 2.0, 9.81 + 0.01 * i),
            np.zeros(9),
        )

    def wrench(sec: float, i: int):
        w = t["geometry_msgs/msg/Wrench"](vec(float(i), 0.5, 40.0 + i), vec(0.0, 0.0, 0.0))
        return t["geometry_msgs/msg/WrenchStamped"](hdr(sec, "fl", i), w)

    return imu, wrench


def _write(writer, serialize, ts, seconds: float) -> None:
    """An IMU at 100 Hz and a foot wrench at 50 Hz through an open rosbags writer."""
    imu, wrench = _messages(ts)
    c_imu = writer.add_connection("/robot/imu", "sensor_msgs/msg/Imu", typestore=ts)
    c_foot = writer.add_connection("/robot/feet/fl", "geometry_msgs/msg/WrenchStamped", typestore=ts)
    for i in range(int(seconds * RATE)):
        t = 1000.0 + i / RATE
        writer.write(c_imu, int(t * 1e9), serialize(imu(t, i), "sensor_msgs/msg/Imu"))
        if i % 2 == 0:
            writer.write(c_foot, int(t * 1e9), serialize(wrench(t, i), "geometry_msgs/msg/WrenchStamped"))


def write_ros1(path: Path, seconds: float = 2.0) -> Path:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        _write(w, ts.serialize_ros1, ts, seconds)
    return path


def write_ros2(folder: Path, seconds: float = 2.0) -> Path:
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(folder, version=8) as w:
        _write(w, ts.serialize_cdr, ts, seconds)
    return next(folder.glob("*.db3"))


@pytest.mark.parametrize("kind", ["ros1", "ros2"])
def test_a_bag_is_read_like_the_same_mcap(tmp_path: Path, kind: str) -> None:
    """Wall 12: most public legged-robot datasets are ROS 1 bags; ROS 2 records SQLite bags."""
    path = write_ros1(tmp_path / "walk.bag") if kind == "ros1" else write_ros2(tmp_path / "walk")
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([path])
    assert log.format == "bag" and log.rate_hz == RATE and log.n_samples == 199
    names = log.channel_names
    assert "imu/angular_velocity.x" in names and "fl/force.z" in names and not any("torque" in n for n in names)
    x = np.asarray(s.rows(log.id)[:])
    i = names.index("imu/angular_velocity.x")
    np.testing.assert_allclose(x[:10, i], 0.1 * np.arange(10), atol=1e-6)  # header stamps on the 100 Hz grid
    f = names.index("fl/force.z")
    np.testing.assert_allclose(x[:6, f], [40, 40, 42, 42, 44, 44], atol=1e-6)  # 50 Hz held between samples


def test_a_damaged_bag_is_refused_in_one_line(tmp_path: Path) -> None:
    path = write_ros1(tmp_path / "walk.bag")
    data = path.read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    s = Session.create(tmp_path / "s")
    with pytest.raises(IngestError, match=r"cut\.bag: (not a readable ROS bag|truncated or corrupt bag)") as err:
        s.ingest([cut])
    assert "\n" not in str(err.value) and s.logs() == []


def test_a_bags_dry_run_mapping_round_trips(tmp_path: Path, capsys) -> None:
    from sessions import load_mapping
    from workbench.cli import main

    path = write_ros1(tmp_path / "walk.bag")
    assert main(["ingest", str(tmp_path / "s"), str(path), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "[bag]" in out and "topic /robot/imu (sensor_msgs/msg/Imu" in out
    mapping = tmp_path / "m.toml"
    mapping.write_text(out)
    chans = load_mapping(mapping).channels
    assert ("/robot/feet/fl", "wrench.force.z", "fl/force.z") in [(c.source, c.field, c.name) for c in chans]
    main(["new", str(tmp_path / "s")])
    assert main(["ingest", str(tmp_path / "s"), str(path), "--mapping", str(mapping)]) == 0
    (log,) = Session.open(tmp_path / "s").logs()
    assert len(log.channel_names) == len(chans) == 13
