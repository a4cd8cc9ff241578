"""The optional HMM over step probabilities: it mends scattered errors, the causal pass reads no future step, the
robot's streaming runtime filters as the offline forward pass does, and a change is followed later the longer a
terrain is expected to last."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from training import StreamingClassifier, TerrainFilter, load_bundle

GOLDEN = Path(__file__).parent / "golden"


def noisy_steps(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Three terrains in blocks of 400 steps; the classifier right 70 % of the time, its errors scattered."""
    rng = np.random.default_rng(seed)
    truth = np.repeat([0, 1, 2, 0, 2], 400)
    guess = np.where(rng.random(len(truth)) < 0.7, truth, rng.integers(0, 3, len(truth)))
    probs = np.full((len(truth), 3), 0.15)
    probs[np.arange(len(truth)), guess] = 0.7
    return probs, truth


def test_smoothing_mends_scattered_errors_and_the_causal_pass_reads_no_future_step() -> None:
    probs, truth = noisy_steps()
    raw = (probs.argmax(1) == truth).mean()
    hmm = TerrainFilter.for_dwell(4.0, 100.0, 3)  # 400 steps on a terrain at 100 Hz
    causal, offline = hmm.forward(probs), hmm.smooth(probs)
    assert np.allclose(causal.sum(1), 1.0) and np.allclose(offline.sum(1), 1.0)
    assert raw < 0.85 < (causal.argmax(1) == truth).mean() <= (offline.argmax(1) == truth).mean(), raw
    changed = probs.copy()
    changed[1000:] = changed[1000:, ::-1]  # another future from step 1000
    np.testing.assert_array_equal(hmm.forward(changed)[:1000], causal[:1000])
    assert not np.allclose(hmm.smooth(changed)[:1000], offline[:1000])  # forward-backward does read it


def test_the_delay_grows_with_the_time_on_a_terrain_and_falls_with_confidence() -> None:
    short, long = (TerrainFilter.for_dwell(s, 50.0, 4) for s in (1.0, 20.0))
    assert 0 < short.delay_steps(0.8) < long.delay_steps(0.8) < 100_000
    assert long.delay_steps(0.95) < long.delay_steps(0.6)
    # the measured delay is what the filter does on a clean change
    probs = np.full((600, 4), 0.2 / 3)
    probs[:300, 0] = probs[300:, 3] = 0.8
    flip = int(np.argmax(long.forward(probs)[300:].argmax(1) == 3))
    assert flip == long.delay_steps(0.8)
    for bad in (0.0, -1.0, float("nan"), float("inf"), 86_401.0):  # inf: forward-backward gave NaN (issue 64)
        with pytest.raises(ValueError, match="above 0 and at most 86400"):
            TerrainFilter.for_dwell(bad, 50.0, 4)
    day = TerrainFilter.for_dwell(86_400.0, 100.0, 4)  # the longest: every belief stays finite
    assert np.isfinite(day.smooth(np.random.default_rng(0).dirichlet(np.ones(4), 5000))).all()


@pytest.mark.parametrize("name", ["paper", "default"])
def test_the_streaming_runtime_filters_as_the_offline_forward_pass(name: str) -> None:
    bundle = load_bundle(GOLDEN / name)
    x = np.load(GOLDEN / "log.npy")
    raw = StreamingClassifier(bundle).run(x)  # (T, K)
    clf = StreamingClassifier(bundle, smooth_s=0.5)
    filtered = clf.run(x)
    np.testing.assert_allclose(filtered, clf.filter.forward(raw), rtol=0, atol=1e-5)
    clf.reset()  # a new log: the filter's state is forgotten too
    np.testing.assert_allclose(clf.run(x), filtered, rtol=0, atol=1e-6)
