"""The spectral front end: the right bins, causal, the stream equal to the offline pass, slow channels found."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from training import (
    SpectralConfig,
    SpectralStream,
    frame_ends,
    frame_features,
    per_step,
    split_channels,
    summary_windows,
)


def _log(n: int = 1000, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    fast = np.sin(2 * np.pi * 25.0 * t) + 0.1 * rng.normal(size=n)  # 25 Hz at 100 Hz
    held = np.repeat(rng.normal(size=n // 15 + 1), 15)[:n]  # a 6.7 Hz stream held at 100 Hz
    return np.column_stack([fast, held]).astype(np.float32)


def test_a_sine_lands_in_its_bin_and_slow_channels_are_found() -> None:
    x = _log()
    fast, slow = split_channels(x)
    assert fast == (0,) and slow == (1,)
    cfg = SpectralConfig(frame=40, hop=20, fast=fast, slow=slow)
    f = frame_features(x, cfg)
    assert f.shape == (len(frame_ends(len(x), cfg)), cfg.width) == (49, 21 + 4)
    # 25 Hz in 40-sample frames at 100 Hz: bin 25 / (100 / 40) = 10
    assert (f[:, :21].argmax(axis=1) == 10).all()
    stats = f[:, 21:]  # mean, std, min, max of the held channel over each frame
    np.testing.assert_allclose(
        stats[0], [x[:40, 1].mean(), x[:40, 1].std(), x[:40, 1].min(), x[:40, 1].max()], rtol=1e-5
    )


def test_features_are_causal() -> None:
    x = _log()
    cfg = SpectralConfig(fast=(0,), slow=(1,))
    before, known = per_step(frame_features(x, cfg), len(x), cfg)
    changed = x.copy()
    changed[500:] = 99.0
    after, _ = per_step(frame_features(changed, cfg), len(x), cfg)
    np.testing.assert_array_equal(before[:500], after[:500])  # nothing after step 499 reaches step 499
    assert not known[:39].any() and known[39:].all()
    assert not np.array_equal(before[519], after[519])  # the frame ending at 519 holds changed samples


def test_the_stream_gives_the_offline_features() -> None:
    logs = [_log(300, seed=1), _log(300, seed=2)]
    cfg = SpectralConfig(frame=40, hop=20, fast=(0,), slow=(1,))
    offline = [per_step(frame_features(x, cfg), len(x), cfg) for x in logs]
    stream = SpectralStream(cfg, 2, streams=2)
    for t in range(300):
        feats, known = stream.step(np.stack([logs[0][t], logs[1][t]]))
        for b in range(2):
            assert known[b] == offline[b][1][t]
            np.testing.assert_allclose(feats[b], offline[b][0][t], rtol=1e-4, atol=1e-4)


def test_summary_windows_are_mean_and_spread_of_the_last_frames() -> None:
    frames = np.random.default_rng(3).normal(size=(30, 4)).astype(np.float32)
    s = summary_windows(frames, frames_per_window=8)
    assert s.shape == (30, 8)
    np.testing.assert_allclose(s[20, :4], frames[13:21].mean(0), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(s[20, 4:], frames[13:21].std(0), rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(s[2, :4], frames[:3].mean(0), rtol=1e-5, atol=1e-6)  # short at the start


def _resident_file_kb() -> int:
    """This process's resident pages of mapped files (``RssFile``, Linux)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("RssFile:"):
            return int(line.split()[1])
    pytest.skip("no RssFile in /proc/self/status (not Linux)")


def test_drop_pages_gives_back_what_a_pass_over_a_memory_map_made_resident(tmp_path: Path) -> None:
    """Issue 66: a pass over every log's cached frames must not leave them all resident (3.3 GB at 100 h)."""
    from training.spectral_cnn.spectra import drop_pages, frame_moments

    path = tmp_path / "frames.npy"
    np.save(path, np.arange(12_000_000, dtype=np.float32).reshape(-1, 6))  # 48 MB
    frames = np.load(path, mmap_mode="r")
    before = _resident_file_kb()
    total = float(frames[:, 0].astype(np.float64).sum())
    read = _resident_file_kb()
    drop_pages(frames[10:])  # a view of the map finds it too
    after = _resident_file_kb()
    assert read - before > 30_000 and read - after > 30_000, (before, read, after)
    assert float(frames[:, 0].astype(np.float64).sum()) == total  # still readable, from the file
    drop_pages(np.ones(3))  # an array in memory: nothing to give back
    drop_pages(frames)
    after = _resident_file_kb()
    mean, _ = frame_moments([np.load(path, mmap_mode="r")])
    assert abs(mean[0] - np.arange(0, 12_000_000, 6).mean()) < 1.0
    assert _resident_file_kb() - after < 30_000  # the pass left its pages out of the resident set


def test_the_pool_and_the_labels_rows_leave_the_mapped_frames_they_read_out_of_the_resident_set(tmp_path: Path) -> None:
    """Issue 66: the pool copies its rows; the frames it read them from (every log's, on a fleet's hours) must not
    stay resident beside that copy (0.9 GiB of a 100 h train's 3.2 GiB peak)."""
    from training.spectral_cnn.spectra import SpectralSteps
    from training.spectral_cnn.stretch_pool import PSEUDO_STRIDE, every_row, stretch_pool
    from training.spectral_cnn.window_rows import window_rows

    cfg = SpectralConfig(frame=40, hop=20, fast=(0,), slow=(1,))
    rng = np.random.default_rng(0)
    path = tmp_path / "frames.npy"
    np.save(path, rng.standard_normal((100_000, cfg.width)).astype(np.float32))  # 10 MB of frames
    frames = np.load(path, mmap_mode="r")
    steps = SpectralSteps(frames, len(frames) * cfg.hop, cfg)
    stretches = [(0, a, a + 500_000) for a in range(0, 2_000_000, 500_000)]
    before = _resident_file_kb()
    pool, bounds = stretch_pool([steps], stretches, PSEUDO_STRIDE)
    assert _resident_file_kb() - before < 2_000, "the pass left the frames it read resident"
    every = steps.frame_rows(500_000, 1_000_000)[::PSEUDO_STRIDE]
    assert np.array_equal(pool[bounds[1] : bounds[2]], steps.at(every))  # and the rows are still the frames'
    steps.release()
    before = _resident_file_kb()
    rows, ends = window_rows([steps], [(0, 0, 1_000_000), (0, 1_500_000, 2_000_000)], every_row)  # as a fit's labels
    assert _resident_file_kb() - before < 2_000, "the labels' rows left the frames they read resident"
    assert np.array_equal(rows[ends[1] : ends[2]], steps.at(every_row(steps, 1_500_000, 2_000_000)))
    assert np.array_equal(rows[: ends[1]], steps.at(every_row(steps, 0, 1_000_000)))  # its first windows repeat


def test_step_rows_span_means_are_the_means_of_the_steps_sliced() -> None:
    from training import StepRows

    rng = np.random.default_rng(5)
    for frame, hop, n_samples, n_frames in [(40, 20, 1000, 49), (7, 3, 200, 80), (40, 20, 1000, 10), (1, 1, 50, 50)]:
        rows = StepRows(
            rng.normal(size=(n_frames, 3)).astype(np.float16), n_samples, SpectralConfig(frame=frame, hop=hop)
        )
        starts = rng.integers(0, n_samples, 40)
        stops = np.minimum(starts + rng.integers(1, 300, 40), n_samples)
        want = [np.asarray(rows[a:b], np.float64).mean(axis=0) for a, b in zip(starts, stops, strict=True)]
        np.testing.assert_allclose(rows.segment_means(starts, stops), want, atol=1e-9)
