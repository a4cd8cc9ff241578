"""The MiniRocket family end to end on arrays: per-step windows, the fit with its folds, the bundle, and the stream
and ONNX giving the offline numbers."""

from __future__ import annotations

import numpy as np
import pytest

from training import (
    HELD_OUT,
    Normalizer,
    RawSteps,
    RocketClassifier,
    RocketTransform,
    SpectralConfig,
    StreamingClassifier,
    WindowFitConfig,
    check_onnx,
    export_onnx,
    family,
    fit_rocket_steps,
    load_bundle,
    run_classifiers,
    save_bundle,
)

from .test_window_family import RATE, _walk, window_bundle

LENGTH, HOP = 120, 20


@pytest.fixture(scope="module")
def small_rocket():
    """Tests check what the fit does, not how well: 840 features instead of 9,996."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("training.minirocket.rocket_steps_fit.FEATURES", 840)
        yield


@pytest.fixture(scope="module")
def fitted(small_rocket):
    rng = np.random.default_rng(0)
    terrains = [0, 1, 2] * 3
    arrays = [_walk(1800, k, rng) for k in terrains]
    normalizer = Normalizer.fit(arrays)
    feats = [RawSteps(a, length=LENGTH, hop=HOP, transform=normalizer) for a in arrays]
    segments = [(i, 300, 900, k) for i, k in enumerate(terrains)]
    fit = fit_rocket_steps(feats, segments, ("a", "b", "c"), config=WindowFitConfig(k_folds=3))
    bundle = window_bundle(fit, normalizer, SpectralConfig.for_log(arrays[0], RATE))  # the frame front end kept
    return bundle, arrays, feats, fit


def test_raw_steps_hold_the_last_hops_window_with_zeros_before_the_start() -> None:
    rows = np.arange(100, dtype=np.float32).reshape(50, 2)
    steps = RawSteps(rows, length=4, hop=3, transform=lambda x: x + 1)
    assert steps.shape == (50, 8)
    got = steps[0:7].reshape(7, 4, 2)
    assert not got[:2].any()  # no hop yet: zeros
    np.testing.assert_array_equal(got[2:5], np.broadcast_to([[0, 0], [0, 0], [1, 2], [3, 4], [5, 6]][1:], (3, 4, 2)))
    np.testing.assert_array_equal(got[5, -1], rows[5] + 1)  # the hop at step 5 ends its window there
    np.testing.assert_array_equal(steps.hop_rows(0, 12), [2, 5, 8, 11])
    np.testing.assert_array_equal(steps.at(np.array([11, 49])).reshape(2, 4, 2)[1], rows[44:48] + 1)


def test_the_fit_measures_its_folds_and_held_out_logs_and_tells_the_terrains_apart(fitted) -> None:
    _, _, _, fit = fitted
    assert len(fit.models) == 3 and fit.metrics["out_of_fold"]
    assert fit.metrics["accuracy"] > 0.9
    assert fit.metrics["held_out_logs"]["accuracy"] > 0.9
    assert fit.metrics["estimate"]["kind"] == HELD_OUT
    assert 0.0 < fit.metrics["calibration"]["temperature"] < 10.0
    assert fit.metrics["calibration"]["on"] == "held-out logs"
    # one transform for the whole ensemble: only the heads differ
    a, b = fit.models[0], fit.models[1]
    assert np.array_equal(a.transform.biases.numpy(), b.transform.biases.numpy())
    assert not np.array_equal(a.head.weight.detach().numpy(), b.head.weight.detach().numpy())


def test_past_the_row_budget_each_terrain_keeps_its_share_and_a_floor(small_rocket, fitted) -> None:
    """Issue 66: the heads read at most ``ROWS`` labelled hop rows, a draw of each terrain's in proportion with
    ``FLOOR`` rows at least (a briefly labelled terrain is not drawn away); under the budget, every row."""
    _, _, feats, fit = fitted
    assert fit.metrics["rows_read"] == [270, 270]  # 9 logs x 600 labelled steps / a hop of 20: all read
    terrains = [0, 1, 2] * 3
    segments = [(i, 300, 900 if k < 2 else 400, k) for i, k in enumerate(terrains)]  # 90, 90 and 15 rows
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("training.minirocket.rocket_steps_fit.ROWS", 60)
        mp.setattr("training.minirocket.rocket_steps_fit.FLOOR", 20)
        small = fit_rocket_steps(feats, segments, ("a", "b", "c"), config=WindowFitConfig(k_folds=3))
    # 28 + 28 by their shares of 60, and all 15 of the third (under the floor)
    assert small.metrics["rows_read"] == [71, 195]
    assert small.metrics["held_out_logs"]["accuracy"] > 0.9
    assert small.metrics["per_class_recall"]["c"] > 0.5


def test_bundle_stream_and_onnx_give_the_offline_numbers(fitted, tmp_path) -> None:
    bundle, arrays, feats, _ = fitted
    loaded = load_bundle(save_bundle(bundle, tmp_path / "b"))
    assert loaded.family == "minirocket" and loaded.classifiers[0].config.hop == HOP
    assert "MiniRocket family" in family("minirocket").describe(loaded)
    offline = run_classifiers(loaded.classifiers, feats[:1])[0].mean(0)[:400]  # (T, K): 20 hops
    np.testing.assert_allclose(StreamingClassifier(loaded).run(arrays[0][:400]), offline, atol=1e-5)
    two = StreamingClassifier(loaded, streams=2)
    both = np.stack([two.step(np.stack([arrays[0][t], arrays[1][t]])) for t in range(120)])  # (T, 2, K)
    np.testing.assert_allclose(both[:, 0], offline[:120], atol=1e-5)
    assert check_onnx(export_onnx(loaded, tmp_path / "m.onnx"), loaded, arrays[0][:80]) < 1e-4


def test_the_offline_pass_runs_the_shared_transform_once_and_gives_each_members_numbers(fitted, monkeypatch) -> None:
    _, _, feats, fit = fitted
    calls = []
    forward = RocketTransform.forward
    monkeypatch.setattr(RocketTransform, "forward", lambda self, x: calls.append(len(x)) or forward(self, x))
    together = run_classifiers(fit.models, feats[:2])
    once = sum(calls)
    monkeypatch.setattr(RocketClassifier, "ensemble_forward", staticmethod(lambda members: None))
    calls.clear()
    apart = run_classifiers(fit.models, feats[:2])
    assert sum(calls) == len(fit.models) * once  # each member ran the transform over the same windows
    for a, b in zip(together, apart, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-6)


def test_one_terrain_labelled_is_refused_in_one_line(fitted) -> None:
    _, _, feats, _ = fitted
    with pytest.raises(ValueError, match="two terrains"):
        fit_rocket_steps(feats, [(0, 300, 900, 0), (3, 300, 900, 0)], ("a", "b", "c"))
