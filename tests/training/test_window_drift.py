"""The default family's drift score and temperature: drifted logs score high and training logs low, the reference
survives a bundle round trip, the temperature is fitted where it can be and folded into the heads."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
import torch

from training import (
    BundleError,
    Normalizer,
    SpectralConfig,
    SpectralSteps,
    WindowClassifier,
    WindowClassifierConfig,
    WindowFitConfig,
    drift_of_log,
    fit_temperature,
    fit_window_classifier,
    load_bundle,
    log_frames,
    save_bundle,
    scale_head,
)

from .test_window_family import RATE, _walk, window_bundle


def _shifted(n: int, rng: np.random.Generator) -> np.ndarray:
    """A log unlike any terrain of :func:`_walk`: its fast channel vibrates at 48 Hz, four times as strong, and its
    slow channel sits far off."""
    t = np.arange(n) / RATE
    fast = 4.0 * np.sin(2 * np.pi * 48.0 * t) + 0.5 * rng.normal(size=n)
    held = np.repeat(rng.normal(size=n // 15 + 1) + 5.0, 15)[:n]
    return np.column_stack([fast, rng.normal(size=n), held]).astype(np.float32)


@pytest.fixture(scope="module")
def drift_fit():
    rng = np.random.default_rng(3)
    terrains = [0, 1, 2] * 2
    arrays = [_walk(2400, k, rng) for k in terrains]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    feats = [SpectralSteps(log_frames(a, config, transform=normalizer), len(a), config) for a in arrays]
    segments = [(i, 300, 1200, k) for i, k in enumerate(terrains)]
    fit = fit_window_classifier(feats, segments, ("a", "b", "c"), config=WindowFitConfig(k_folds=3, epochs=30))
    return arrays, normalizer, config, feats, fit


def test_drift_is_low_on_the_training_logs_and_high_on_a_shifted_log(drift_fit) -> None:
    _, normalizer, config, feats, fit = drift_fit
    assert fit.drift is not None and len(fit.drift.references) == len(fit.models)
    rng = np.random.default_rng(9)
    new_same = [_walk(2400, k, rng) for k in (0, 1, 2)]  # new logs of the terrains it knows
    shifted = _shifted(2400, rng)

    def drift(a: np.ndarray) -> np.ndarray:
        steps = SpectralSteps(log_frames(a, config, transform=normalizer), len(a), config)
        return drift_of_log(fit.drift, fit.models, steps)

    for f in feats:  # its own logs, labelled and unlabelled parts alike
        d = drift_of_log(fit.drift, fit.models, f)
        assert d.shape == (f.shape[0],) and np.isfinite(d).all()
        assert np.mean(d > 1.0) < 0.2, np.mean(d > 1.0)
    for a in new_same:
        assert np.mean(drift(a) > 1.0) < 0.3
    d_shift = drift(shifted)
    assert np.mean(d_shift > 1.0) > 0.9, np.mean(d_shift > 1.0)
    assert np.median(d_shift) > 2 * max(np.median(drift(a)) for a in new_same)


def test_the_bundle_keeps_the_drift_reference_and_refuses_one_that_does_not_fit(drift_fit, tmp_path) -> None:
    _, normalizer, config, feats, fit = drift_fit
    bundle = window_bundle(fit, normalizer, config)
    loaded = load_bundle(save_bundle(bundle, tmp_path / "b"))
    assert loaded.drift is not None
    np.testing.assert_array_equal(loaded.drift.scales, fit.drift.scales)
    np.testing.assert_allclose(
        drift_of_log(loaded.drift, loaded.classifiers, feats[0]), drift_of_log(fit.drift, fit.models, feats[0])
    )
    # a bundle from before the drift score: no score, no error
    old = load_bundle(save_bundle(replace(bundle, drift=None), tmp_path / "old"))
    assert old.drift is None
    # model.json claiming more members than the reference holds
    cfg = json.loads((tmp_path / "b" / "model.json").read_text())
    cfg["drift"]["members"] = 7
    (tmp_path / "b" / "model.json").write_text(json.dumps(cfg))
    with pytest.raises(BundleError, match="damaged"):
        load_bundle(tmp_path / "b")


def test_the_temperature_is_recovered_and_folded_into_the_head_without_changing_the_argmax() -> None:
    rng = np.random.default_rng(0)
    z = rng.normal(size=(4000, 4)) * 2.0  # (N, K) calibrated logits
    p = np.exp(z) / np.exp(z).sum(1, keepdims=True)
    truth = np.array([rng.choice(4, p=row) for row in p])
    assert fit_temperature(3.0 * z, truth) == pytest.approx(3.0, rel=0.08)  # overconfident thrice: T = 3
    assert fit_temperature(z, truth) == pytest.approx(1.0, rel=0.08)
    assert fit_temperature(np.zeros((0, 4)), np.zeros(0, int)) == 1.0

    torch.manual_seed(0)
    model = WindowClassifier(WindowClassifierConfig(14, 3, window=7, hidden=8)).eval()
    x = torch.randn(50, 14)
    before = model.logits(x).detach()
    scale_head(model, 2.5)
    after = model.logits(x).detach()
    torch.testing.assert_close(after, before / 2.5)
    assert torch.equal(after.argmax(1), before.argmax(1))


def test_the_temperature_comes_from_held_out_recordings_when_a_terrain_is_in_two(drift_fit) -> None:
    *_, feats, fit = drift_fit
    cal = fit.metrics["calibration"]
    assert cal["on"] in ("held-out logs", None) and cal["n"] > 0  # every terrain in two logs: held-out logs
    if cal["on"] is not None:
        assert cal["temperature"] != 1.0
    segments = [(i, 300, 1200, k) for i, k in enumerate([0, 1, 2] * 2)]
    # the six logs as two recordings of three: one terrain each, so no held-out figure, and the blocked folds
    # calibrate (a same-run figure)
    one_run = fit_window_classifier(
        feats,
        segments,
        ("a", "b", "c"),
        config=WindowFitConfig(k_folds=3, epochs=10, self_training=False),
        groups=[0, 1, 2, 0, 1, 2],
    )
    assert "held_out_logs" not in one_run.metrics
    assert one_run.metrics["calibration"]["on"] in ("same run", None)
    off = fit_window_classifier(
        feats, segments, ("a", "b", "c"), config=WindowFitConfig(k_folds=3, epochs=10, calibrate=False)
    )
    assert off.metrics["calibration"] == {"temperature": 1.0, "on": None, "n": off.metrics["calibration"]["n"]}
