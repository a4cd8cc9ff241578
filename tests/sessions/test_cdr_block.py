"""Header-and-floats ROS 2 messages decoded a block at a time: the layout read from the schema, the same streams as
the library's per-message decoder, and anything unexpected left to that decoder."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sessions import IngestOptions
from sessions.ingest import mcap_reader
from sessions.ingest.cdr_block import decode_block, float64_fields
from workbench.demo import (
    COMPRESSED_IMAGE_SCHEMA,
    IMU_SCHEMA,
    WRENCH_STAMPED_SCHEMA,
    generate_walk,
    write_walk,
)
from workbench.demo import encode_stamped_floats as encode


def test_the_layout_of_imu_and_wrench_and_no_layout_for_other_shapes() -> None:
    imu = float64_fields(IMU_SCHEMA)
    assert imu is not None and len(imu) == 37  # quaternion 4, three covariances of 9, two vectors of 3
    assert imu[("orientation", "w")] == 3 and imu[("orientation_covariance", 8)] == 12
    assert imu[("angular_velocity", "x")] == 13 and imu[("linear_acceleration", "z")] == 27
    wrench = float64_fields(WRENCH_STAMPED_SCHEMA)
    axes = [("wrench", v, k) for v in ("force", "torque") for k in "xyz"]
    assert wrench == {p: i for i, p in enumerate(axes)}
    assert float64_fields(COMPRESSED_IMAGE_SCHEMA) is None  # a string and a sequence after the header
    assert float64_fields(IMU_SCHEMA.replace("float64[9] orientation_covariance", "int32 flags")) is None
    assert float64_fields(IMU_SCHEMA.replace("std_msgs/Header header\n", "")) is None  # no header first


def test_decode_block_reads_the_floats_and_flags_what_does_not_fit() -> None:
    stamps = np.array([1000.25, 1000.5, 0.0])
    values = np.arange(18, dtype=np.float64).reshape(3, 6)
    buf, size = encode(stamps, values, "fl_foot")
    datas = [buf[i * size : (i + 1) * size] for i in range(3)]
    odd, _ = encode(stamps[:1], values[:1], "a_longer_frame_id")  # another length: a group of its own
    datas.append(odd)
    datas.append(datas[0][:-8])  # cut short: left to the library
    datas.append(b"\x00\x00" + datas[0][2:])  # big-endian encapsulation: left to the library
    got_stamps, got, ok = decode_block(datas, 6)
    assert ok.tolist() == [True, True, True, True, False, False]
    np.testing.assert_array_equal(got[:3], values)
    np.testing.assert_array_equal(got[3], values[0])
    np.testing.assert_allclose(got_stamps[:2], stamps[:2], atol=1e-6)
    assert np.isnan(got_stamps[2])  # a zero stamp: the log time is used, as for the library's decoder


def _read(path: Path, options: IngestOptions, *, blocks: bool, monkeypatch: pytest.MonkeyPatch):
    if not blocks:
        monkeypatch.setattr(mcap_reader, "_block_layout", lambda channel, schema: None)
    parsed, _ = mcap_reader.read_mcap(path, options)
    monkeypatch.undo()
    return parsed


def test_block_decoding_reads_the_same_streams_as_the_library(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_walk(generate_walk(5, 60.0), tmp_path / "walk.mcap", seed=5)
    options = IngestOptions(camera_fps=0)
    fast = _read(path, options, blocks=True, monkeypatch=monkeypatch)
    slow = _read(path, options, blocks=False, monkeypatch=monkeypatch)
    assert [s.channels for s in fast.streams] == [s.channels for s in slow.streams]
    for a, b in zip(fast.streams, slow.streams, strict=True):
        assert a.units == b.units and a.sources == b.sources
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_array_equal(a.values[0 : len(a.times)], b.values[0 : len(b.times)])
