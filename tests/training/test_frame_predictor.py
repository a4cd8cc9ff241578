"""The default family's frame predictor: it learns (beats copying the last frame on a log it never saw), its
surprise peaks where the terrain changes, and scoring a log in chunks gives the numbers of one pass."""

from __future__ import annotations

import numpy as np
import pytest

from training import (
    FramePredictor,
    FramePredictorFit,
    Normalizer,
    SpectralConfig,
    copy_last_error,
    fit_frame_predictor,
    frame_surprise,
    log_frames,
)

from .test_window_family import RATE, _walk

FIT = FramePredictorFit(steps=150, batch=16, crop=48)


def _floor(n: int, rough: bool, rng: np.random.Generator) -> np.ndarray:
    """Two terrains that differ across the spectrum: a soft floor (noise smoothed over 8 samples: little above
    12 Hz) or a rough one (white noise, twice as strong), on two fast channels and a held slow one."""
    white = rng.normal(size=(n + 7, 2))
    fast = 2.0 * white[7:] if rough else np.stack([np.convolve(w, np.ones(8) / 8, "valid") for w in white.T], 1)
    held = np.repeat(rng.normal(size=n // 15 + 1) + (0.5 if rough else 0.0), 15)[:n]
    return np.column_stack([fast, held]).astype(np.float32)


@pytest.fixture(scope="module")
def trained():
    rng = np.random.default_rng(1)
    arrays = [_walk(3000, k, rng) for k in (0, 1, 2, 0, 1, 2)]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    frames = [log_frames(a, config, transform=normalizer) for a in arrays]
    model, history = fit_frame_predictor(frames, fit=FIT)
    return model, history, normalizer, config, rng


def test_it_learns_past_copying_the_last_frame_on_a_new_log(trained) -> None:
    model, history, normalizer, config, rng = trained
    assert history[-1] < history[0]
    held = log_frames(_walk(3000, 1, rng), config, transform=normalizer)  # a walk it never saw
    error, hidden = frame_surprise(model, held, raw=True)
    baseline = copy_last_error(model, held)
    assert error[7:].mean() < 0.8 * baseline[7:].mean()
    assert hidden.shape == (len(held), model.config.hidden)


def test_surprise_peaks_where_the_terrain_changes() -> None:
    rng = np.random.default_rng(2)
    arrays = [_floor(6000, rough, rng) for rough in (False, True, False, True)]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    model, _ = fit_frame_predictor([log_frames(a, config, transform=normalizer) for a in arrays], fit=FIT)
    joined = np.concatenate([_floor(3000, False, rng), _floor(3000, True, rng)])  # the change at sample 3000
    frames = log_frames(joined, config, transform=normalizer)
    error, _ = frame_surprise(model, frames)
    # the log's start, predicted from zeros before it, is no surprise; in the loss's units it is measured
    assert not error[: FramePredictor.context].any()
    assert frame_surprise(model, frames, raw=True)[0][1 : FramePredictor.context].all()
    track = np.convolve(error, np.ones(4) / 4)[: len(error)]  # the last four frames' mean, as a smoothed highlight
    ends = np.arange(config.frame - 1, len(joined), config.hop)  # the sample at which each frame completes
    peak = ends[np.argmax(track)]
    assert 3000 <= peak <= 3000 + 2 * RATE, f"surprise peaks at sample {peak}, the terrain changes at 3000"
    assert track.max() > 3 * np.median(track[10:])


def test_chunks_give_one_pass_numbers(trained) -> None:
    model, _, normalizer, config, rng = trained
    frames = log_frames(_walk(4000, 2, rng), config, transform=normalizer)
    whole_error, whole_hidden = frame_surprise(model, frames)
    error, hidden = frame_surprise(model, frames, chunk=13)
    np.testing.assert_allclose(error, whole_error, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(hidden, whole_hidden, rtol=1e-4, atol=1e-5)


def test_too_short_logs_are_refused() -> None:
    with pytest.raises(ValueError, match="long enough"):
        fit_frame_predictor([np.zeros((1, 5), np.float32)], fit=FIT)
