"""Alignment of multi-rate streams: causal hold, duplicate stamps, gaps, rate choice, reference truth."""

from __future__ import annotations

import numpy as np
import pytest

from sessions import IngestError, IngestOptions
from sessions.ingest import ParsedLog, Stream, align


def stream(name: str, times, values) -> Stream:
    values = np.asarray(values, dtype=np.float64).reshape(len(times), -1)
    k = values.shape[1]
    return Stream(
        name,
        np.asarray(times, np.float64),
        values,
        tuple(f"{name}/{i}" for i in range(k)),
        ("",) * k,
        tuple(f"src:{i}" for i in range(k)),
    )


def log(*streams: Stream, reference=()) -> ParsedLog:
    return ParsedLog("x", "x.mcap", ("x.mcap",), "mcap", tuple(streams), reference=tuple(reference))


def test_slow_streams_are_held_never_looked_ahead() -> None:
    fast = stream("fast", np.arange(0, 1.0, 0.01), np.arange(100))
    slow = stream("slow", np.arange(0, 1.0, 0.1) + 0.005, np.arange(10) * 10)  # 5 ms after the fast grid
    out = align(log(fast, slow), IngestOptions())
    assert out.rate_hz == 100.0
    assert out.t0 == pytest.approx(0.005)
    grid = out.t0 + np.arange(out.data.shape[0]) / out.rate_hz
    held = 10 * np.floor((grid - 0.005 + 1e-9) / 0.1)
    np.testing.assert_allclose(out.data[:, 1], held)  # the value of the latest slow sample at or before t
    np.testing.assert_allclose(out.data[:, 0], np.floor(grid * 100 + 1e-6))
    assert out.stream_rates == pytest.approx({"fast": 100.0, "slow": 10.0})


def test_duplicate_stamps_collapse_to_the_last() -> None:
    s = stream("s", [0.0, 0.01, 0.01, 0.02, 0.03], [1, 2, 3, 4, 5])
    out = align(log(s), IngestOptions())
    np.testing.assert_array_equal(out.data[:, 0], [1, 3, 4, 5])


def test_grid_spans_only_the_time_all_streams_share() -> None:
    a = stream("a", np.arange(0, 2, 0.01), np.zeros(200))
    b = stream("b", np.arange(0.5, 1.5, 0.02), np.ones(50))
    out = align(log(a, b), IngestOptions())
    assert out.t0 == pytest.approx(0.5)
    assert out.data.shape[0] == pytest.approx(0.98 * 100 + 1, abs=1)


def test_streams_that_share_no_time_are_refused() -> None:
    a = stream("a", [0.0, 0.1, 0.2], [1, 2, 3])
    b = stream("b", [5.0, 5.1], [1, 2])
    with pytest.raises(IngestError, match="share no time span"):
        align(log(a, b), IngestOptions())


def test_a_dropout_is_refused_by_default_and_recorded_with_allow_gaps() -> None:
    t = np.r_[np.arange(0, 1, 0.01), np.arange(2, 3, 0.01)]  # one second with no data
    s = stream("imu", t, np.arange(len(t)))
    with pytest.raises(IngestError, match=r"no data for 1\.010 s .* in stream 'imu'; use --allow-gaps") as err:
        align(log(s), IngestOptions())
    assert err.value.where == "t=0.990 s"
    out = align(log(s), IngestOptions(allow_gaps=True))
    (gap,) = out.gaps
    assert gap.stream == "imu"
    assert gap.start == 99  # the last sample before the silence
    assert gap.stop == 200  # data is fresh again at t = 2.0 s
    assert np.isfinite(out.data).all()


def test_short_jitter_is_not_a_gap() -> None:
    rng = np.random.default_rng(0)
    t = np.cumsum(0.01 + rng.uniform(-0.002, 0.002, 500))
    t[250] += 0.02  # a late sample: 3 periods, under the 5-period threshold
    out = align(log(stream("s", np.sort(t), np.arange(500))), IngestOptions())
    assert out.gaps == ()


def test_rate_override_and_reference_in_samples() -> None:
    s = stream("s", np.arange(0, 10, 0.01), np.arange(1000))
    out = align(log(s, reference=[(0.0, 4.0, "grass"), (4.0, 12.0, "sand")]), IngestOptions(rate_hz=50.0))
    assert out.rate_hz == 50.0
    assert out.data.shape[0] == 500  # 9.99 s at 50 Hz, both ends included
    assert out.reference == ((0, 200, "grass"), (200, 500, "sand"))


def test_stamps_too_sparse_for_a_sensor_are_refused_not_divided_by_zero() -> None:
    """Found by the CSV fuzz target: two stamps 23 days apart made a rate of 0 Hz and a division by zero."""
    with pytest.raises(IngestError, match=r"sample rate .* Hz: the stamps are not those of a sensor log"):
        align(log(stream("a", [-2_000_000.0, 0.0], [0.0, 1.0])), IngestOptions())
