"""Small MCAP files written with mcap-ros2-support's own encoder (independent of the demo's vectorised one)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mcap.writer import Writer as RawWriter
from mcap_ros2.writer import Writer

from workbench.demo import (
    AMCL_SCHEMA,
    DRIVER_GNSS_SCHEMA,
    IMU_SCHEMA,
    ODOMETRY_SCHEMA,
    TF_SCHEMA,
    WRENCH_STAMPED_SCHEMA,
)

VECTOR3_STAMPED_SCHEMA = IMU_SCHEMA[IMU_SCHEMA.index("=" * 80) :].replace(
    "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n" + "=" * 80 + "\n", ""
)
VECTOR3_STAMPED_SCHEMA = "std_msgs/Header header\ngeometry_msgs/Vector3 vector\n" + VECTOR3_STAMPED_SCHEMA

# A custom robot message carrying an Imu and four foot wrenches, as a real robot stack might publish.
ROBOT_STATE_SCHEMA = f"""std_msgs/Header header
uint32 seq
sensor_msgs/Imu imu
geometry_msgs/Wrench[4] feet
{"=" * 80}
MSG: sensor_msgs/Imu
{IMU_SCHEMA.split(chr(10) + "=" * 80)[0]}
{"=" * 80}
MSG: geometry_msgs/Wrench
geometry_msgs/Vector3 force
geometry_msgs/Vector3 torque
{IMU_SCHEMA[IMU_SCHEMA.index("=" * 80) :]}"""


def stamp(t: float) -> dict:
    sec = int(t)
    return {"sec": sec, "nanosec": round((t - sec) * 1e9)}


def header(t: float, frame: str = "base") -> dict:
    return {"stamp": stamp(t), "frame_id": frame}


def vec(x: float, y: float, z: float) -> dict:
    return {"x": x, "y": y, "z": z}


def imu_msg(t: float, i: int) -> dict:
    return {
        "header": header(t, "imu"),
        "orientation": {"x": 0.0, "y": 0.0, "z": np.sin(i / 50), "w": np.cos(i / 50)},
        "orientation_covariance": [0.0] * 9,
        "angular_velocity": vec(0.1 * i, -0.2 * i, 0.3),
        "angular_velocity_covariance": [0.0] * 9,
        "linear_acceleration": vec(1.0, 2.0, 9.81 + 0.01 * i),
        "linear_acceleration_covariance": [0.0] * 9,
    }


def write_ros2_sensors(path: Path, *, seconds: float = 2.0, t0: float = 1000.0, zero_stamps: bool = False) -> Path:
    """Imu at 100 Hz, two WrenchStamped feet at 50 Hz, a Vector3Stamped at 20 Hz, plus a std_msgs/String topic.

    With ``zero_stamps`` the header stamps are 0 and the log time must be used instead.
    """
    with open(path, "wb") as f:
        w = Writer(f)
        imu_s = w.register_msgdef("sensor_msgs/msg/Imu", IMU_SCHEMA)
        wr_s = w.register_msgdef("geometry_msgs/msg/WrenchStamped", WRENCH_STAMPED_SCHEMA)
        v_s = w.register_msgdef("geometry_msgs/msg/Vector3Stamped", VECTOR3_STAMPED_SCHEMA)
        str_s = w.register_msgdef("std_msgs/msg/String", "string data")
        for i in range(int(seconds * 100)):
            t = t0 + i / 100
            log_ns = round((t + 0.5) * 1e9)  # the recorder's clock is 0.5 s later than the stamps
            msg = imu_msg(0.0 if zero_stamps else t, i)
            w.write_message("/robot/imu", imu_s, msg, log_time=log_ns, publish_time=log_ns)
            if i % 2 == 0:
                for foot, sign in (("fl", 1.0), ("fr", -1.0)):
                    m = {
                        "header": header(0.0 if zero_stamps else t, foot),
                        "wrench": {"force": vec(sign * i, 0.5, 40.0 + i), "torque": vec(0.0, 0.0, 0.0)},
                    }
                    w.write_message(f"/robot/feet/{foot}", wr_s, m, log_time=log_ns, publish_time=log_ns)
            if i % 5 == 0:
                m = {"header": header(0.0 if zero_stamps else t), "vector": vec(i, i, i)}
                w.write_message("/robot/contact", v_s, m, log_time=log_ns, publish_time=log_ns)
            w.write_message("/chatter", str_s, {"data": f"hello {i}"}, log_time=log_ns, publish_time=log_ns)
        w.finish()
    return path


def write_nested(path: Path, *, n: int = 200, t0: float = 50.0) -> Path:
    """A custom ``robot/msg/State`` holding an Imu and ``Wrench[4]``, at 100 Hz."""
    with open(path, "wb") as f:
        w = Writer(f)
        s = w.register_msgdef("robot/msg/State", ROBOT_STATE_SCHEMA)
        for i in range(n):
            t = t0 + i / 100
            feet = [{"force": vec(k, 0.0, 10.0 * k + i), "torque": vec(0.0, 0.0, 0.0)} for k in range(4)]
            msg = {"header": header(t), "seq": i, "imu": imu_msg(t, i), "feet": feet}
            ns = int(t * 1e9)
            w.write_message("/state", s, msg, log_time=ns, publish_time=ns)
        w.finish()
    return path


def write_json_channel(path: Path, *, n: int = 100, bad_at: int | None = None) -> Path:
    """A JSON-encoded IMU-shaped channel at 100 Hz, without a header: log time is used."""
    with open(path, "wb") as f:
        w = RawWriter(f)
        w.start(profile="", library="test")
        schema = w.register_schema("imu", "jsonschema", b"{}")
        ch = w.register_channel("/json_imu", "json", schema)
        for i in range(n):
            msg = {
                "angular_velocity": {"x": 0.1 * i, "y": 0.0, "z": 0.0},
                "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.8},
            }
            data = json.dumps(msg).encode() if i != bad_at else b"{not json"
            w.add_message(ch, log_time=int(1e9 + i * 1e7), data=data, publish_time=int(1e9 + i * 1e7))
        w.finish()
    return path


def path_at(t: float) -> tuple[float, float]:
    """The fixtures' robot: a circle of 10 m radius at 1 m/s, from (10, 0)."""
    return 10.0 * np.cos(t / 10.0), 10.0 * np.sin(t / 10.0)


def write_with_poses(
    path: Path, *, seconds: float = 4.0, t0: float = 1000.0, wild_fix: bool = False, small_robot: bool = False
) -> Path:
    """An Imu at 100 Hz with the robot's position three ways: ``nav_msgs/Odometry`` and ``/tf`` (odom ->
    base_link, and a camera frame beside it) at 20 Hz, and a GNSS driver's own fix message at 5 Hz (``wild_fix``:
    one of them 1,000 km off, one at latitude 95°). ``small_robot``: odometry, ``/tf`` and an AMCL pose
    (``geometry_msgs/PoseWithCovarianceStamped`` in ``map``) only, as a small ROS 2 robot records."""
    quat = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    with open(path, "wb") as f:
        w = Writer(f)
        imu_s = w.register_msgdef("sensor_msgs/msg/Imu", IMU_SCHEMA)
        odom_s = w.register_msgdef("nav_msgs/msg/Odometry", ODOMETRY_SCHEMA)
        tf_s = w.register_msgdef("tf2_msgs/msg/TFMessage", TF_SCHEMA)
        fix_s = w.register_msgdef("acme_gnss/msg/Fix", DRIVER_GNSS_SCHEMA)
        amcl_s = w.register_msgdef("geometry_msgs/msg/PoseWithCovarianceStamped", AMCL_SCHEMA)
        for i in range(int(seconds * 100)):
            t = t0 + i / 100
            ns = round(t * 1e9)
            if not small_robot:
                w.write_message("/imu", imu_s, imu_msg(t, i), log_time=ns, publish_time=ns)
            x, y = path_at(i / 100)
            if i % 5 == 0:
                twist = {"linear": vec(1.0, 0.0, 0.0), "angular": vec(0.0, 0.0, 0.1)}
                odom = {
                    "header": header(t, "odom"),
                    "child_frame_id": "base_link",
                    "pose": {"pose": {"position": vec(x, y, 0.0), "orientation": quat}, "covariance": [0.0] * 36},
                    "twist": {"twist": twist, "covariance": [0.0] * 36},
                }
                w.write_message("/odom", odom_s, odom, log_time=ns, publish_time=ns)
                tf = {
                    "transforms": [
                        {
                            "header": header(t, "odom"),
                            "child_frame_id": "base_link",
                            "transform": {"translation": vec(x, y, 0.0), "rotation": quat},
                        },
                        {
                            "header": header(t, "base_link"),
                            "child_frame_id": "camera",
                            "transform": {"translation": vec(0.2, 0.0, 0.5), "rotation": quat},
                        },
                    ]
                }
                w.write_message("/tf", tf_s, tf, log_time=ns, publish_time=ns)
            if small_robot and i % 50 == 0:
                amcl = {
                    "header": header(t, "map"),
                    "pose": {"pose": {"position": vec(x + 2.0, y, 0.0), "orientation": quat}, "covariance": [0.0] * 36},
                }
                w.write_message("/amcl_pose", amcl_s, amcl, log_time=ns, publish_time=ns)
            if i % 20 == 0 and not small_robot:
                lat, lon = 45.38 + y / 111_195.0, -71.92 + x / 78_200.0
                if wild_fix and i == 100:
                    lat += 9.0
                if wild_fix and i == 200:
                    lat = 95.0
                fix = {
                    "header": header(t, "gnss"),
                    "fix_quality": 4,
                    "latitude": lat,
                    "longitude": lon,
                    "altitude": 250.0,
                    "hdop": 0.8,
                }
                w.write_message("/gnss/fix", fix_s, fix, log_time=ns, publish_time=ns)
        w.finish()
    return path
