"""The demo walks as real ROS 2 MCAP files: IMU and foot wrenches, a downward camera, and the ground truth beside.

Topics: ``/imu`` (``sensor_msgs/msg/Imu``, 100 Hz) and ``/feet/{fl,fr,rl,rr}``
(``geometry_msgs/msg/WrenchStamped``, 50 Hz, on a clock offset from the IMU's), so alignment is exercised; with the
camera, ``/camera/ground/compressed``. Ground truth goes to ``<log>.truth.json`` beside each log, for evaluation
only.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .ground_camera import ground_frames
from .walks import FEET, FOOT_HZ, IMU_HZ, Walk, generate_walk


def write_walk(walk: Walk, path: str | Path, *, seed: int = 0, camera: bool = True, positions: bool = True) -> Path:
    """Write a walk as a ROS 2 MCAP file (zstd chunks) plus its ``.truth.json`` sidecar; with ``camera``, a
    downward camera's JPEGs too (``/camera/ground/compressed``, 5 frames a second); with ``positions``, where it
    walked (``/odom`` at 10 Hz, ``/gnss/fix`` at 5 Hz: ``field_path``)."""
    from mcap.writer import CompressionType, Writer

    from .ros2_cdr import (
        COMPRESSED_IMAGE_SCHEMA,
        IMU_SCHEMA,
        WRENCH_STAMPED_SCHEMA,
        compressed_image,
        encode,
        imu_values,
        wrench_values,
    )

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed + 7919)
    step = int(IMU_HZ // FOOT_HZ)
    # Feet run on their own clock: offset by 3 ms and jittered, so alignment has real work to do.
    foot_idx = np.arange(0, len(walk.times), step)
    foot_t = walk.t0 + walk.times[foot_idx] + 0.003 + rng.normal(0, 0.0004, foot_idx.size)
    imu_t = walk.t0 + walk.times
    # (channel, stamps, buffer of fixed-size records and their size, or a list of variable-size messages and 0)
    records: list[tuple[int, np.ndarray, bytes | list[bytes], int]] = []

    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as f:
        writer = Writer(f, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="terrain-workbench demo")
        imu_schema = writer.register_schema("sensor_msgs/msg/Imu", "ros2msg", IMU_SCHEMA.encode())
        wrench_schema = writer.register_schema(
            "geometry_msgs/msg/WrenchStamped", "ros2msg", WRENCH_STAMPED_SCHEMA.encode()
        )
        ch = writer.register_channel("/imu", "cdr", imu_schema)
        buf, size = encode(imu_t, imu_values(walk.quat, walk.gyro, walk.accel), "imu_link")
        records.append((ch, imu_t, buf, size))
        for j, foot in enumerate(FEET):
            ch = writer.register_channel(f"/feet/{foot}", "cdr", wrench_schema)
            buf, size = encode(foot_t, wrench_values(walk.forces[foot_idx, j]), f"{foot}_foot")
            records.append((ch, foot_t, buf, size))
        if camera:
            image_schema = writer.register_schema(
                "sensor_msgs/msg/CompressedImage", "ros2msg", COMPRESSED_IMAGE_SCHEMA.encode()
            )
            ch = writer.register_channel("/camera/ground/compressed", "cdr", image_schema)
            cam_t, jpegs = ground_frames(walk, seed=seed)
            messages = [compressed_image(t, "camera", "jpeg", j) for t, j in zip(cam_t, jpegs, strict=True)]
            records.append((ch, cam_t, messages, 0))
        if positions:  # where the robot walked: odometry and a GNSS fix, on the field whose patches are the terrains
            records += _position_records(writer, walk, rng)
        # Interleave all topics in time order, as a recorder would.
        chan = np.concatenate([np.full(len(r[1]), i) for i, r in enumerate(records)])
        row = np.concatenate([np.arange(len(r[1])) for r in records])
        stamps = np.concatenate([r[1] for r in records])
        order = np.argsort(stamps, kind="stable")
        ns = np.round(stamps[order] * 1e9).astype(np.int64).tolist()
        views = [memoryview(r[2]) if r[3] else r[2] for r in records]
        sizes = [r[3] for r in records]
        ids = [r[0] for r in records]
        add = writer.add_message
        for c, r, t_ns in zip(chan[order].tolist(), row[order].tolist(), ns, strict=True):
            size = sizes[c]
            add(ids[c], t_ns, views[c][r * size : (r + 1) * size] if size else views[c][r], t_ns)
        writer.finish()
    tmp.replace(path)

    truth = {
        "log": path.name,
        "clock": "absolute seconds, on the messages' header stamps",
        "segments": [{"start": walk.t0 + a, "stop": walk.t0 + b, "terrain": k} for a, b, k in walk.truth],
    }
    path.with_name(path.stem + ".truth.json").write_text(json.dumps(truth, indent=1))
    return path


def generate_demo_logs(
    out_dir: str | Path, *, n_logs: int = 6, minutes: float = 5.0, seed: int = 0, progress: bool = False
) -> list[Path]:
    """Write ``n_logs`` walks of about ``minutes`` each (lengths vary ±30 %) to ``out_dir``.

    Returns:
        The MCAP paths, in order.
    """
    import os
    from concurrent.futures import ProcessPoolExecutor

    from tqdm import tqdm

    rng = np.random.default_rng(seed)
    jobs = [
        (
            seed * 1000 + i,
            float(minutes * 60 * rng.uniform(0.7, 1.3)),
            1.7e9 + 86400 * seed + 3600 * i,
            Path(out_dir) / f"walk_{i:03d}.mcap",
        )
        for i in range(n_logs)
    ]
    workers = min(len(jobs), os.cpu_count() or 1)
    bar = dict(total=len(jobs), desc="demo logs", unit="log", disable=not progress)
    # Writing is bound by the mcap library's per-message cost, so walks are written one per core.
    if workers <= 1:
        return list(tqdm(map(_write_job, jobs), **bar))
    with ProcessPoolExecutor(workers) as pool:
        return list(tqdm(pool.map(_write_job, jobs), **bar))


def _write_job(job: tuple[int, float, float, Path]) -> Path:
    seed, duration, t0, path = job
    return write_walk(generate_walk(seed, duration, t0=t0), path, seed=seed)


ODOM_HZ, FIX_HZ, FIX_SIGMA_M, FIELD_ALT_M = 10.0, 5.0, 0.1, 180.0  # an RTK-grade fix


def _position_records(writer, walk: Walk, rng: np.random.Generator) -> list:
    """The walk's odometry (from where it started, in ``odom``) and GNSS fixes (the field's, with 0.1 m of noise)
    as records for :func:`write_walk`'s interleaving."""
    from .field_path import field_positions, to_fix
    from .pose_schemas import NAVSATFIX_SCHEMA, ODOMETRY_SCHEMA
    from .ros2_cdr import navsatfix, odometry

    field = field_positions(walk)  # (T, 2)
    out = []
    odom_schema = writer.register_schema("nav_msgs/msg/Odometry", "ros2msg", ODOMETRY_SCHEMA.encode())
    at = np.arange(0, len(walk.times), int(IMU_HZ // ODOM_HZ))
    step = np.diff(field[at], axis=0, prepend=field[at][:1])
    yaw = np.arctan2(step[:, 1], step[:, 0])
    speed = np.hypot(step[:, 0], step[:, 1]) * ODOM_HZ
    turn = np.diff(np.unwrap(yaw), prepend=yaw[:1]) * ODOM_HZ
    stamps = walk.t0 + walk.times[at]
    local = field[at] - field[0]  # odometry starts at zero where the walk starts
    messages = [
        odometry(t, (float(x), float(y)), float(h), float(v), float(w))
        for t, (x, y), h, v, w in zip(stamps, local, yaw, speed, turn, strict=True)
    ]
    out.append((writer.register_channel("/odom", "cdr", odom_schema), stamps, messages, 0))
    fix_schema = writer.register_schema("sensor_msgs/msg/NavSatFix", "ros2msg", NAVSATFIX_SCHEMA.encode())
    at = np.arange(0, len(walk.times), int(IMU_HZ // FIX_HZ))
    noisy = field[at] + rng.normal(0.0, FIX_SIGMA_M, (len(at), 2))
    stamps = walk.t0 + walk.times[at]
    fixes = [
        navsatfix(t, float(lat), float(lon), FIELD_ALT_M, sigma_m=FIX_SIGMA_M)
        for t, (lat, lon) in zip(stamps, to_fix(noisy), strict=True)
    ]
    out.append((writer.register_channel("/gnss/fix", "cdr", fix_schema), stamps, fixes, 0))
    return out
