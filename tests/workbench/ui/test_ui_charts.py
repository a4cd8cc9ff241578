"""Decimation and chart building of the browser view: pure functions, checked on hand-made arrays."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from workbench.ui.charts import (
    ROWS,
    TrackInputs,
    channel_groups,
    per_sample_labels,
    trace_chart,
    tracks_chart,
    with_cursor,
)
from workbench.ui.decimate import decimate
from workbench.ui.panel_data import safe_name

NAMES = (
    "imu/orientation.x",
    "imu/orientation.y",
    "imu/orientation.z",
    "imu/orientation.w",
    "imu/angular_velocity.x",
    "imu/angular_velocity.y",
    "imu/angular_velocity.z",
    "fl/force.x",
    "fl/force.y",
    "fl/force.z",
    "fr/force.x",
    "fr/force.y",
    "fr/force.z",
)


def test_short_windows_are_sent_whole() -> None:
    x = np.arange(20, dtype=np.float32).reshape(10, 2)
    d = decimate(x, 5, rate_hz=10.0, pixels=100)
    assert d.step == 1
    np.testing.assert_array_equal(d.values, x)
    np.testing.assert_allclose(d.t, (5 + np.arange(10)) / 10.0)


def test_decimation_keeps_every_bucket_extreme_and_spikes() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(10_000, 3)).astype(np.float32)
    x[4321, 1] = 50.0  # a one-sample spike must survive
    x[777, 2] = -40.0
    d = decimate(x, 0, rate_hz=100.0, pixels=200)
    assert len(d.t) <= 2 * 200 + 2 and np.all(np.diff(d.t) > 0)
    assert d.values[:, 1].max() == 50.0 and d.values[:, 2].min() == -40.0
    for c in range(3):  # the envelope is exactly the per-bucket min and max
        b = np.arange(0, 10_000, d.step)
        assert np.allclose(np.sort(d.values[:, c].reshape(-1, 2), axis=1)[:, 0], np.minimum.reduceat(x[:, c], b))
        assert np.allclose(np.sort(d.values[:, c].reshape(-1, 2), axis=1)[:, 1], np.maximum.reduceat(x[:, c], b))


@pytest.mark.parametrize("n", [10_001, 10_037, 9_999])
def test_a_short_last_bucket_keeps_its_own_extremes_in_order(n: int) -> None:
    rng = np.random.default_rng(n)
    x = rng.normal(size=(n, 2)).astype(np.float32)
    x[-1, 0] = 9.0  # the very last sample is its bucket's maximum
    d = decimate(x, 0, rate_hz=100.0, pixels=200)
    edges = np.arange(0, n, d.step)
    for c in range(2):
        for k, a in enumerate(edges):
            seg = x[a : a + d.step, c]
            i_lo, i_hi = int(seg.argmin()), int(seg.argmax())
            expect = [seg[i_lo], seg[i_hi]] if i_lo <= i_hi else [seg[i_hi], seg[i_lo]]
            assert list(d.values[2 * k : 2 * k + 2, c]) == expect
    assert d.values[-1, 0] == 9.0 and d.t[-2] == edges[-1] / 100.0


def test_decimation_orders_each_pair_as_it_happened() -> None:
    x = np.zeros((1000, 1), np.float32)
    x[10], x[15] = 5.0, -5.0  # 100 pixels over 1000 samples: buckets of 10, and [10, 20) has the max first
    d = decimate(x, 0, rate_hz=1.0, pixels=100)
    pair = d.values[2:4, 0]
    assert list(pair) == [5.0, -5.0]


def test_channel_groups_by_foot_and_by_axis() -> None:
    by_foot = channel_groups(NAMES)
    assert [g.title for g in by_foot] == ["imu/orientation", "imu/angular velocity", "fl/force", "fr/force"]
    assert by_foot[0].names == ("x", "y", "z", "w") and by_foot[2].channels == (7, 8, 9)
    by_axis = channel_groups(NAMES, forces_by="axis")
    titles = [g.title for g in by_axis]
    assert titles[2:] == ["force x", "force y", "force z"]
    assert by_axis[4].channels == (9, 12) and by_axis[4].names == ("fl", "fr")
    assert sorted(i for g in by_axis for i in g.channels) == list(range(len(NAMES)))


def test_cursor_is_a_vertical_line_at_its_time() -> None:
    t = np.array([0.0, 1.0, 2.0, 3.0])
    t2, (c,), line = with_cursor(t, [np.array([0.0, 10.0, 20.0, 30.0])], 1.5)
    assert list(t2) == [0.0, 1.0, 1.5, 1.5, 1.5, 2.0, 3.0]
    assert list(c) == [0.0, 10.0, 15.0, 15.0, 15.0, 20.0, 30.0]
    assert list(line) == [0, 0, 0, 1, 0, 0, 0]
    t3, _, line = with_cursor(t, [t], 9.0)  # outside the window: no line
    assert len(t3) == 4 and not line.any()


def test_charts_have_one_series_per_data_column() -> None:
    x = np.random.default_rng(1).normal(size=(3000, len(NAMES))).astype(np.float32)
    d = decimate(x, 0, rate_hz=100.0, pixels=500)
    for g in channel_groups(NAMES):
        spec = trace_chart(d, g, cursor_s=3.0, show_x=True)
        assert len(spec["data"]) == len(spec["series"]) == len(g.channels) + 2
        assert len({len(a) for a in spec["data"]}) == 1
    p = len(d.t)
    labels = per_sample_labels(3000, [(100, 500, 1), (2000, 2500, 0)])
    assert labels[99] == -1 and labels[100] == 1 and labels[2499] == 0 and labels[2500] == -1
    idx = np.round(d.t * 100).astype(int).clip(0, 2999)
    inputs = TrackInputs(
        d.t,
        labels[idx],
        np.zeros(p, int),
        np.full(p, 0.5),
        np.full(p, 0.2),
        np.zeros(p, bool),
        np.zeros(p, bool),
        np.zeros(p, bool),
        idx < 300,
    )
    spec = tracks_chart(inputs, [("concrete", "#888888"), ("grass", "#2e7d32")], cursor_s=None)
    assert len(spec["data"]) == len(spec["series"])
    series = {s["label"]: i for i, s in enumerate(spec["series"])}
    grass = spec["data"][series["label grass"]]
    assert grass[(idx >= 100) & (idx < 500)].min() == 5.9 and grass[idx >= 600].max() == 5.1  # band up only there
    assert "unlike anything labelled" not in series  # no drift score (the paper family): no drift row
    # a drift track: the band is up where it passes the line (a drift score of 1), the line follows the level
    drift = np.where(idx >= 2000, 0.97, 0.4)
    spec = tracks_chart(replace(inputs, drift=drift), [("concrete", "#888888")], cursor_s=None)
    series = {s["label"]: i for i, s in enumerate(spec["series"])}
    band, level = spec["data"][series["unlike anything labelled"]], spec["data"][series["drift"]]
    lo, hi = ROWS["drift"]
    assert band[idx >= 2000].min() == hi and band[idx < 2000].max() == lo
    np.testing.assert_allclose(level, lo + (hi - lo) * drift)
    assert "drift" in spec["axes"][1]["values"]


def test_upload_names_cannot_leave_the_folder() -> None:
    assert safe_name("../../etc/passwd") == "passwd"
    assert safe_name("..\\..\\x.mcap") == "x.mcap"
    assert safe_name("my log (1).csv") == "my_log_1_.csv"
    assert safe_name("...") == "upload" and safe_name("") == "upload"
