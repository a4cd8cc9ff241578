"""The default family's members and drift once per frame give the step pass's numbers: every step's probabilities
within 1e-5 and the same most probable class, the same drift, blank steps before the first frame."""

from __future__ import annotations

import numpy as np
import torch

from training import (
    Normalizer,
    SpectralConfig,
    SpectralSteps,
    WindowClassifier,
    WindowClassifierConfig,
    blank_probs,
    drift_of_log,
    fit_drift,
    frame_chunks,
    log_frames,
    run_classifiers,
    stacked_frames,
    step_frames,
)

from .test_window_family import RATE, _walk


def _members(config: SpectralConfig, frames: np.ndarray, n: int = 3) -> list[WindowClassifier]:
    torch.manual_seed(0)
    members = []
    for m in range(n):
        model = WindowClassifier(WindowClassifierConfig(n_features=config.step_width, n_classes=3, hidden=8))
        model.set_standardisation(frames.mean(axis=0) + 0.1 * m, frames.std(axis=0) * (1.0 + 0.2 * m))
        members.append(model.eval())
    return members


def test_a_frame_pass_gives_the_step_pass_numbers_and_the_drift_of_log() -> None:
    rng = np.random.default_rng(4)
    arrays = [_walk(1500, k, rng) for k in (0, 1, 2)]
    config = SpectralConfig.for_log(arrays[0], RATE)
    normalizer = Normalizer.fit(arrays)
    steps = SpectralSteps(log_frames(arrays[2], config, transform=normalizer), len(arrays[2]), config)
    frames = np.asarray(steps.frames)
    models = _members(config, frames)
    rows = [stacked_frames(frames, np.arange(a, len(frames), 3), config.window) for a in range(3)]
    drift = fit_drift(models, rows, [rows[(m + 1) % 3] for m in range(3)])

    parts = list(frame_chunks(models, steps, drift=drift, chunk=17))  # chunks that cut the log's frames unevenly
    assert [p.start for p in parts] == list(range(0, len(frames), 17))
    per_frame = np.concatenate([p.probs for p in parts], axis=1)  # (M, N, K)
    assert per_frame.shape == (3, len(frames), 3)
    which = step_frames(steps)  # (T,)
    assert which.shape == (len(steps),) and (which[: config.frame - 1] == -1).all() and which[-1] == len(frames) - 1
    blank = blank_probs(models)[:, None]  # (M, 1, K)
    per_step = np.where((which >= 0)[None, :, None], per_frame[:, np.maximum(which, 0)], blank)  # (M, T, K)

    (stepped,) = run_classifiers(models, [steps])  # (M, T, K) the step pass
    np.testing.assert_allclose(per_step, stepped, atol=1e-5)
    assert (per_step.argmax(-1) == stepped.argmax(-1)).all()
    assert not np.allclose(blank[:, 0], per_frame[:, 0], atol=1e-3)  # the blank input is not the first frame's

    # the drift: to 1e-5 at the default chunk (measured 1.3e-7: the 1x1 mixing runs once per frame, a product over
    # other rows than drift_of_log's windows); batched otherwise, the last bits of an embedding move and the nearest
    # distances' |q|² + |r|² - 2 q·r magnifies them
    expected = drift_of_log(drift, models, steps)  # (T,)
    whole = np.concatenate([p.drift for p in frame_chunks(models, steps, drift=drift)])[np.clip(which, 0, None)]
    np.testing.assert_allclose(whole, expected, rtol=1e-5)
    drifted = np.concatenate([p.drift for p in parts])[np.clip(which, 0, None)]  # (T,)
    np.testing.assert_allclose(drifted, expected, rtol=1e-3)
    assert all(p.drift is None for p in frame_chunks(models, steps, chunk=500))  # no reference, no drift
