"""Camera frames: image topics of MCAP files and bags are kept as JPEG beside the log, at a bounded rate, and read
back by time; damaged camera files are refused with one line."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sessions import IngestOptions, Session, SessionError
from sessions.ingest import read_source
from sessions.ingest.sources import plan_sources
from tests.sessions.test_ingest_bag import RATE, _messages
from workbench.demo import generate_demo_logs


@pytest.fixture(scope="module")
def demo_mcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    (path,) = generate_demo_logs(tmp_path_factory.mktemp("cam"), n_logs=1, minutes=0.25, seed=4)
    return path


def _picture(jpeg: bytes) -> np.ndarray:
    image = Image.open(io.BytesIO(jpeg))
    assert image.format == "JPEG"
    return np.asarray(image.convert("RGB"), np.float64)


def test_mcap_frames_are_kept_at_the_rate_cap_and_found_by_time(tmp_path: Path, demo_mcap: Path) -> None:
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([demo_mcap])
    (cam,) = s.cameras(log.id)
    assert cam.topic == "/camera/ground/compressed" and (cam.width, cam.height) == (192, 144)
    # the demo camera records 5 frames a second; the session keeps at most 2 a second
    assert abs(cam.frames - 2 * log.duration_s) <= 2
    times = s.camera_times(log.id)
    assert np.all(np.diff(times) > 0) and times[0] < 0.5 and times[-1] > log.duration_s - 1.0
    for cursor in (0.0, 3.3, log.duration_s / 2, log.duration_s - 0.2):
        frame = s.camera_frame(log.id, cursor)
        # one frame kept per half second of a 5 Hz camera: kept frames are 0.4 to 0.6 s apart, the nearest within 0.3
        assert frame is not None and abs(frame.t - cursor) <= 0.3 + 1e-3
        assert _picture(frame.jpeg).shape == (144, 192, 3)
    assert s.camera_frame(log.id, log.duration_s + 5.0) is None  # past the camera: nothing, not a stale picture
    a, b = s.camera_frame(log.id, 1.0), s.camera_frame(log.id, 6.0)
    assert a is not None and b is not None and a.jpeg != b.jpeg  # the ground moves with the walk


def test_thumbnails_and_the_frames_of_a_stretch(tmp_path: Path, demo_mcap: Path) -> None:
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([demo_mcap])
    small = s.camera_thumbnail(log.id, 3.3)
    full = _picture(s.camera_frame(log.id, 3.3).jpeg)
    assert _picture(small).shape == (84, 112, 3)  # 112 px wide, the frame's 4:3 kept
    shrunk = np.asarray(Image.fromarray(full.astype(np.uint8)).resize((112, 84), Image.BILINEAR), np.float64)
    assert np.abs(_picture(small) - shrunk).mean() < 12  # the same picture, not another frame's
    assert s.camera_thumbnail(log.id, 3.3) is small  # kept: a table redrawn reads and decodes nothing again
    assert s.camera_thumbnail(log.id, log.duration_s + 5.0) is None
    numbers = s.camera_frames_between(log.id, 2.0, 6.0)
    times = s.camera_times(log.id)
    assert numbers == [i for i, t in enumerate(times) if 2.0 <= t < 6.0] and len(numbers) == 8
    frame = s.camera_frame_by_number(log.id, numbers[0])
    assert frame.number == numbers[0] and frame.t == times[numbers[0]] and frame.jpeg[:2] == b"\xff\xd8"


def test_no_camera_frames_when_the_cap_is_zero(tmp_path: Path, demo_mcap: Path) -> None:
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([demo_mcap], options=IngestOptions(camera_fps=0))
    assert s.cameras(log.id) == []
    assert not list((s.path / "logs").glob("*.frames"))


def _image_bag(path: Path, *, encoding: str, width: int = 32, height: int = 24, seconds: float = 3.0) -> Path:
    """A ROS 1 bag with an IMU, a foot and a raw camera at 10 Hz whose picture is a colour that changes in time."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    imu, wrench = _messages(ts)
    t = ts.types
    channels = {"rgb8": 3, "bgr8": 3, "mono8": 1, "mono16": 1}[encoding]
    with Writer(path) as w:
        c_imu = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        c_foot = w.add_connection("/fl", "geometry_msgs/msg/WrenchStamped", typestore=ts)
        c_cam = w.add_connection("/camera/image_raw", "sensor_msgs/msg/Image", typestore=ts)
        for i in range(int(seconds * RATE)):
            sec = 1000.0 + i / RATE
            w.write(c_imu, int(sec * 1e9), ts.serialize_ros1(imu(sec, i), "sensor_msgs/msg/Imu"))
            w.write(c_foot, int(sec * 1e9), ts.serialize_ros1(wrench(sec, i), "geometry_msgs/msg/WrenchStamped"))
            if i % 10 == 0:
                red = i / (seconds * RATE)  # 0 -> 1 over the log
                if encoding == "mono16":
                    data = np.full((height, width), int(red * 60000), "<u2")
                    data[:, : width // 2] = 0  # a left half that stays black, so the range is not flat
                    raw = data.tobytes()
                else:
                    px = np.zeros((height, width, channels), np.uint8)
                    px[..., 0 if encoding == "rgb8" else -1] = int(50 + 200 * red)
                    raw = px.tobytes()
                whole = int(sec)
                header = t["std_msgs/msg/Header"](
                    seq=i,
                    stamp=t["builtin_interfaces/msg/Time"](sec=whole, nanosec=round((sec - whole) * 1e9)),
                    frame_id="camera",
                )
                step = len(raw) // height
                msg = t["sensor_msgs/msg/Image"](header, height, width, encoding, 0, step, np.frombuffer(raw, np.uint8))
                w.write(c_cam, int(sec * 1e9), ts.serialize_ros1(msg, "sensor_msgs/msg/Image"))
    return path


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "mono8", "mono16"])
def test_raw_images_of_a_bag_become_jpeg_with_their_colours(tmp_path: Path, encoding: str) -> None:
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([_image_bag(tmp_path / "walk.bag", encoding=encoding)])
    (cam,) = s.cameras(log.id)
    assert cam.topic == "/camera/image_raw" and (cam.width, cam.height) == (32, 24)
    early, late = s.camera_frame(log.id, 0.2), s.camera_frame(log.id, 2.6)
    assert early is not None and late is not None
    a, b = _picture(early.jpeg), _picture(late.jpeg)
    if encoding in ("rgb8", "bgr8"):  # red in both: BGR is swapped to RGB
        assert b[..., 0].mean() > a[..., 0].mean() + 100
        assert b[..., 2].mean() < 20 and b[..., 1].mean() < 20
    elif encoding == "mono8":  # channel 0 of a one-channel picture: grey rising
        assert b.mean() > a.mean() + 50
    else:  # 16-bit: scaled to its own range, the right half bright once the value is above zero
        assert b[:, 20:].mean() > 200 and b[:, :10].mean() < 30


def test_a_large_jpeg_is_reencoded_within_the_size_bound(tmp_path: Path) -> None:
    from sessions.ingest.image_topics import MAX_SIDE, frame_jpeg

    out = io.BytesIO()
    Image.fromarray(np.full((1080, 1920, 3), 90, np.uint8)).save(out, format="JPEG")

    class Msg:
        format = "jpeg"
        data = out.getvalue()

    jpeg, width, height = frame_jpeg(Msg(), "sensor_msgs/msg/CompressedImage")
    assert (width, height) == (MAX_SIDE, 360) and _picture(jpeg).shape == (360, MAX_SIDE, 3)
    small = io.BytesIO()
    Image.fromarray(np.full((120, 160, 3), 90, np.uint8)).save(small, format="JPEG")
    Msg.data = small.getvalue()
    assert frame_jpeg(Msg(), "sensor_msgs/CompressedImage")[0] == Msg.data  # kept as recorded
    Msg.format = "16UC1; compressedDepth png"
    with pytest.raises(ValueError, match="depth"):
        frame_jpeg(Msg(), "sensor_msgs/CompressedImage")


def test_the_dry_run_says_what_the_camera_gives(demo_mcap: Path) -> None:
    (source,), _ = plan_sources([demo_mcap])
    parsed, reports = read_source(source, IngestOptions())
    (camera,) = [r for r in reports if r.topic == "/camera/ground/compressed"]
    assert camera.unusable is None and "frames kept (at most 2 a second)" in camera.note
    assert len(parsed[0].cameras) == 1


def test_damaged_camera_files_are_refused_with_one_line(tmp_path: Path, demo_mcap: Path) -> None:
    s = Session.create(tmp_path / "s")
    (log,) = s.ingest([demo_mcap])
    index = next((s.path / "logs").glob("*.idx"))
    records = np.load(index)
    records["size"][3] = 1 << 40  # past the end of the frames file
    with open(index, "wb") as f:
        np.save(f, records)
    with pytest.raises(SessionError, match="index does not match its frames") as err:
        s.camera_frame(log.id, 1.0)
    assert "\n" not in str(err.value)
    s.close()
    frames = next((tmp_path / "s" / "logs").glob("*.frames"))
    frames.unlink()
    frames.symlink_to("/etc/passwd")
    with Session.open(tmp_path / "s") as again, pytest.raises(SessionError, match="link or no regular file"):
        again.camera_frame(log.id, 1.0)
