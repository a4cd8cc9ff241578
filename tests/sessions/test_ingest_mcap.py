"""MCAP ingest: ROS 2 sensor types, nested and JSON messages, stamps, mappings, and refusing bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sessions import IngestError, IngestOptions, Session, load_mapping
from tests.conftest import snapshot

from .mcap_fixtures import write_json_channel, write_nested, write_ros2_sensors


def col(session: Session, log_id: int, name: str) -> np.ndarray:
    info = session.log(log_id)
    return session.samples(log_id)[:, info.channel_names.index(name)]


def test_ros2_imu_wrench_vector3_are_recognised_and_aligned(session: Session, tmp_path: Path) -> None:
    (log,) = session.ingest([write_ros2_sensors(tmp_path / "r.mcap")])
    assert log.format == "mcap" and log.rate_hz == 100.0
    assert log.t0 == pytest.approx(1000.0)  # header stamps, not the recorder's log time (+0.5 s)
    names = log.channel_names
    assert names[:10] == (
        "imu/orientation.x",
        "imu/orientation.y",
        "imu/orientation.z",
        "imu/orientation.w",
        "imu/angular_velocity.x",
        "imu/angular_velocity.y",
        "imu/angular_velocity.z",
        "imu/linear_acceleration.x",
        "imu/linear_acceleration.y",
        "imu/linear_acceleration.z",
    )
    assert {"fl/force.x", "fr/force.z", "contact/x"} <= set(names)
    assert not any("torque" in n for n in names)  # all-zero torque is an unused field, dropped
    assert not any("chatter" in n for n in names)
    k = np.arange(log.n_samples)
    np.testing.assert_allclose(col(session, log.id, "imu/angular_velocity.x"), 0.1 * k, rtol=1e-6)
    # feet at 50 Hz are held on the 100 Hz grid: odd samples repeat the previous even one, never the next
    np.testing.assert_allclose(col(session, log.id, "fl/force.x"), k - k % 2)
    np.testing.assert_allclose(col(session, log.id, "fr/force.x"), -(k - k % 2))
    np.testing.assert_allclose(col(session, log.id, "contact/x"), k - k % 5)
    sources = {c.name: c.source for c in log.channels}
    assert sources["fl/force.z"] == "/robot/feet/fl:wrench.force.z"


def test_log_time_is_used_when_header_stamps_are_zero(session: Session, tmp_path: Path) -> None:
    (log,) = session.ingest([write_ros2_sensors(tmp_path / "z.mcap", zero_stamps=True)])
    assert log.t0 == pytest.approx(1000.5)


def test_sensor_messages_nested_in_a_custom_message(session: Session, tmp_path: Path) -> None:
    (log,) = session.ingest([write_nested(tmp_path / "n.mcap")])
    assert log.n_channels == 10 + 4 * 3
    assert "state/feet[3].force.z" in log.channel_names
    np.testing.assert_allclose(col(session, log.id, "state/feet[3].force.z"), 30 + np.arange(log.n_samples))
    assert log.t0 == pytest.approx(50.0)


def test_json_encoded_channel(session: Session, tmp_path: Path) -> None:
    (log,) = session.ingest([write_json_channel(tmp_path / "j.mcap")])
    assert log.channel_names[0] == "json_imu/angular_velocity.x"
    np.testing.assert_allclose(col(session, log.id, "json_imu/angular_velocity.x"), 0.1 * np.arange(100), rtol=1e-6)


def test_demo_walk_round_trips_through_mcap(session: Session, demo_mcap: Path) -> None:
    from workbench.demo import generate_walk

    walk = generate_walk(3, 90.0)
    (log,) = session.ingest([demo_mcap])
    data = session.samples(log.id)
    # IMU at 100 Hz lands on the grid one to one
    np.testing.assert_allclose(data[:, 4:7], walk.gyro[: log.n_samples], atol=1e-5)
    np.testing.assert_allclose(data[:, 7:10], walk.accel[: log.n_samples], atol=1e-4)
    # reference truth from the sidecar, in samples, covering the log, never turned into labels
    ref = session.reference(log.id)
    assert {r[2] for r in ref} == {t for _, _, t in walk.truth}
    assert ref[0][0] == 0 and ref[-1][1] == log.n_samples
    assert session.segments() == []


def test_explicit_mapping_file_picks_fields_and_names(session: Session, tmp_path: Path) -> None:
    mapping = tmp_path / "m.toml"
    mapping.write_text(
        "rate_hz = 50.0\n"
        '[[channels]]\nsource = "/robot/feet/fl"\nfield = "wrench.force.z"\nname = "fl_fz"\nunit = "N"\n'
        '[[channels]]\nsource = "/robot/imu"\nfield = "linear_acceleration.z"\nname = "az"\nunit = "m/s2"\n'
    )
    opts = IngestOptions(mapping=load_mapping(mapping))
    (log,) = session.ingest([write_ros2_sensors(tmp_path / "r.mcap")], options=opts)
    assert log.channel_names == ("imu/az", "fl/fl_fz")  # topics not named in the mapping are not read
    assert [c.unit for c in log.channels] == ["m/s2", "N"]
    assert log.rate_hz == 50.0


def test_bad_mapping_file_is_refused_with_its_name(tmp_path: Path) -> None:
    bad = tmp_path / "m.toml"
    bad.write_text("rate = 3\n")
    with pytest.raises(IngestError, match=r"m\.toml: unknown keys in mapping file: rate"):
        load_mapping(bad)
    bad.write_text("[[channels]]\nfield = 'x'\n")
    with pytest.raises(IngestError, match="bad mapping file"):
        load_mapping(bad)


def _refused(session: Session, path: Path, match: str) -> IngestError:
    before = snapshot(session.path)
    with pytest.raises(IngestError, match=match) as err:
        session.ingest([path])
    assert str(path) in str(err.value)
    assert "\n" not in str(err.value)
    assert snapshot(session.path) == before
    return err.value


def test_empty_and_wrong_magic_and_random_bytes(session: Session, tmp_path: Path) -> None:
    (tmp_path / "empty.mcap").write_bytes(b"")
    _refused(session, tmp_path / "empty.mcap", "empty file")
    (tmp_path / "magic.mcap").write_bytes(b"\x89MCAX0\r\n" + bytes(100))
    assert _refused(session, tmp_path / "magic.mcap", "wrong magic").where == "byte 0"
    rng = np.random.default_rng(1)
    (tmp_path / "rand.mcap").write_bytes(rng.bytes(5000))
    _refused(session, tmp_path / "rand.mcap", "not an MCAP file")


@pytest.mark.parametrize("fraction", [0.02, 0.3, 0.5, 0.77, 0.999])
def test_truncated_file_is_refused_with_a_byte_offset(
    session: Session, demo_mcap: Path, tmp_path: Path, fraction: float
) -> None:
    data = demo_mcap.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * fraction)])
    err = _refused(session, cut, "truncated or corrupt MCAP")
    assert err.where is not None and err.where.startswith("near byte ")


def test_flipped_bytes_in_a_chunk_are_caught(session: Session, demo_mcap: Path, tmp_path: Path) -> None:
    data = bytearray(demo_mcap.read_bytes())
    for i in range(len(data) // 2, len(data) // 2 + 64):
        data[i] ^= 0xFF
    bad = tmp_path / "flip.mcap"
    bad.write_bytes(bytes(data))
    _refused(session, bad, "truncated or corrupt MCAP")


def test_undecodable_message_mid_stream_is_refused_or_a_gap(session: Session, tmp_path: Path) -> None:
    bad = write_json_channel(tmp_path / "j.mcap", bad_at=50)
    err = _refused(session, bad, "message cannot be decoded")
    assert "topic /json_imu" in err.where
    (log,) = session.ingest([bad], options=IngestOptions(allow_gaps=True))
    assert log.gaps == ()  # one dropped message at 100 Hz is within the jitter tolerance
    assert log.n_samples == 100


def test_no_usable_sensor_channel(session: Session, tmp_path: Path) -> None:
    from mcap_ros2.writer import Writer

    path = tmp_path / "chatter.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        s = w.register_msgdef("std_msgs/msg/String", "string data")
        w.write_message("/chatter", s, {"data": "hi"}, log_time=1, publish_time=1)
        w.finish()
    _refused(
        session, path, r"no usable sensor channel \(/chatter: no sensor fields recognised in std_msgs/msg/String\)"
    )


POSE_PARTS = f"""{"=" * 80}
MSG: geometry_msgs/Pose
geometry_msgs/Point position
geometry_msgs/Quaternion orientation
{"=" * 80}
MSG: geometry_msgs/Point
float64 x
float64 y
float64 z
{"=" * 80}
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
{"=" * 80}
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
{"=" * 80}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
POSE_STAMPED_SCHEMA = "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + POSE_PARTS


def test_an_mcap_of_estimates_and_transforms_only_is_refused(session: Session, tmp_path: Path) -> None:
    """Wall 8: odometry, TF and pose topics were read as 27 "sensor" channels; they are estimates, not sensors."""
    from mcap_ros2.writer import Writer

    path = tmp_path / "odom.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        s = w.register_msgdef("geometry_msgs/msg/PoseStamped", POSE_STAMPED_SCHEMA)
        for i in range(50):
            msg = {
                "header": {"stamp": {"sec": 1000, "nanosec": i * 10_000_000}, "frame_id": "map"},
                "pose": {
                    "position": {"x": 0.1 * i, "y": 0.0, "z": 0.0},
                    "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
                },
            }
            w.write_message("/pose", s, msg, log_time=1000 * 10**9 + i * 10**7, publish_time=1)
        w.finish()
    err = _refused(
        session, path, r"no usable sensor channel \(/pose: not a sensor: geometry_msgs/msg/PoseStamped is a pose"
    )
    assert "mapping file" in err.reason
    mapping = tmp_path / "m.toml"  # named in a mapping, it is read: the user decides
    mapping.write_text('[[channels]]\nsource = "/pose"\nfield = "pose.position.x"\nname = "x"\n')
    (log,) = session.ingest([path], options=IngestOptions(mapping=load_mapping(mapping)))
    assert log.channel_names == ("pose/x",)  # named after its topic, as every MCAP channel


def test_one_bad_file_does_not_stop_the_others(session: Session, tmp_path: Path, demo_mcap: Path) -> None:
    (tmp_path / "bad.mcap").write_bytes(b"nope")
    errors: list[IngestError] = []
    logs = session.ingest([tmp_path / "bad.mcap", demo_mcap], on_error=errors.append)
    assert [x.name for x in logs] == ["walk"]
    assert len(errors) == 1 and "bad.mcap" in str(errors[0])


def test_mapping_can_ignore_topics(session: Session, tmp_path: Path) -> None:
    mapping = tmp_path / "m.json"
    mapping.write_text('{"ignore": ["/robot/contact", "/robot/feet/fr"]}')
    opts = IngestOptions(mapping=load_mapping(mapping))
    (log,) = session.ingest([write_ros2_sensors(tmp_path / "r.mcap")], options=opts)
    assert {n.split("/")[0] for n in log.channel_names} == {"imu", "fl"}
