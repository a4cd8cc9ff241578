"""MiniRocket in PyTorch against the numbers aeon computed (``golden/make_minirocket_golden.py``), its fit, and its
classifier on generated windows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from training import RocketTransform, aeon_parameters, fit_rocket, fit_rocket_classifier, rocket_features
from training.minirocket.rocket_kernels import fit_dilations, kernel_outputs, on_grid

GOLDEN = Path(__file__).parent / "golden" / "minirocket_aeon.npz"
ARRAYS = ("per_combination", "indices", "dilations", "per_dilation", "biases")


@pytest.mark.parametrize("case", ["multi", "single"])
def test_the_transform_gives_aeons_features_from_aeons_fit(case: str) -> None:
    g = np.load(GOLDEN)
    x = g[f"{case}_x"]  # (N, C, L)
    _, c, length = x.shape
    dilations, per_dilation = fit_dilations(length, int(g[f"{case}_kernels"]), 32)
    np.testing.assert_array_equal(dilations, g[f"{case}_dilations"])
    np.testing.assert_array_equal(per_dilation, g[f"{case}_per_dilation"])
    params = aeon_parameters(tuple(g[f"{case}_{k}"] for k in ARRAYS), length=length, channels=c)
    with torch.no_grad():
        ours = RocketTransform.from_parameters(params)(torch.as_tensor(x)).numpy()
    want = g[f"{case}_features"]
    assert ours.shape == want.shape
    # our convolution sums in another order than aeon's: a sum within float32 rounding of a bias may fall on the
    # other side, one position of one feature (1 of the 29,988 single-channel features; none of the others)
    differ = ours != want
    assert differ.mean() < 1e-3
    assert np.all(np.abs(ours - want)[differ] <= 1.0 / (length - 8 * dilations.max()) + 1e-6)


def test_the_fits_bias_quantiles_come_from_its_convolutions_in_aeons_order() -> None:
    # the fit's convolution of one window (NumPy, aeon's order of sums) equals the transform's before pooling
    rng = np.random.default_rng(1)
    window = np.cumsum(rng.normal(size=(2, 40)), axis=1).astype(np.float32)
    out = kernel_outputs(window, 3)  # (84, C, L)
    shifted = np.stack([np.roll(np.pad(window, ((0, 0), (12, 12))), -3 * j, axis=1)[:, :40] for j in range(9)])
    k = 0  # taps 0, 1, 2 of weight 2
    want = -shifted.sum(0) + 3 * shifted[[0, 1, 2]].sum(0)
    np.testing.assert_allclose(out[k], want, rtol=1e-5, atol=1e-5)


def test_fit_rocket_draws_channels_and_biases_repeatably() -> None:
    x = np.random.default_rng(0).normal(size=(12, 5, 100)).astype(np.float32)
    a, b = fit_rocket(x, features=840, seed=3), fit_rocket(x, features=840, seed=3)
    assert a.config.features == 840 and a.config.channels == 5 and a.config.length == 100
    np.testing.assert_array_equal(a.biases, b.biases)
    np.testing.assert_array_equal(a.masks, b.masks)
    per_combination = a.masks.sum(2)  # (D, 84)
    assert per_combination.min() >= 1 and per_combination.max() <= 5
    assert not np.array_equal(fit_rocket(x, features=840, seed=4).biases, a.biases)
    with pytest.raises(ValueError, match="L >= 9"):
        fit_rocket(x[:, :, :8])


def _windows(rng: np.random.Generator, n: int, kind: int) -> np.ndarray:
    """``(n, 120, 3)`` windows: terrain 0 a slow wave, terrain 1 fast vibration, terrain 2 (never labelled) noise."""
    t = np.arange(120)[None, :, None]
    phase = rng.uniform(0, 2 * np.pi, (n, 1, 3))
    base = [np.sin(0.1 * t + phase), 0.5 * np.sin(1.3 * t + phase), np.zeros((n, 120, 3))][kind]
    return (base + 0.3 * rng.normal(size=(n, 120, 3))).astype(np.float32)


def test_the_classifier_tells_new_windows_apart_and_never_predicts_a_terrain_with_no_label() -> None:
    rng = np.random.default_rng(0)
    x = np.concatenate([_windows(rng, 40, 0), _windows(rng, 40, 1)])
    y = np.repeat([0, 1], 40)
    model = fit_rocket_classifier(x, y, 3, groups=np.arange(80) // 8, features=840, seed=0)
    new = np.concatenate([_windows(rng, 30, 0), _windows(rng, 30, 1), _windows(rng, 30, 2)])
    with torch.no_grad():
        probs = torch.softmax(model.logits(torch.as_tensor(new.reshape(90, -1))), 1).numpy()
    assert (probs[:60].argmax(1) == np.repeat([0, 1], 30)).mean() > 0.95
    assert probs[:, 2].max() < 1e-6  # no window labelled: never predicted
    assert 0.0 < float(model.temperature) < 10.0
    # the module's features are the transform's, scaled
    feats = rocket_features(model, new[:4])
    with torch.no_grad():
        np.testing.assert_allclose(
            model.features(torch.as_tensor(new[:4].reshape(4, -1))).numpy(), feats * model.scale.numpy(), rtol=1e-6
        )
    with pytest.raises(ValueError, match="two terrains"):
        fit_rocket_classifier(x[:40], y[:40], 3, features=84)


def test_on_the_grid_every_order_of_sums_gives_the_same_features() -> None:
    # on the grid every sum is exact, so aeon's order (NumPy, centre tap first) and ours (one conv1d of each
    # kernel's taps on its channels) must agree to the bit. Off the grid they usually agree too (these windows do);
    # the exported step on demo walks did not (2.6e-4 from PyTorch), which is why the classifier's inputs go on the
    # grid
    rng = np.random.default_rng(2)
    x = on_grid(np.cumsum(rng.normal(size=(5, 3, 90)), axis=2) * 0.3)  # (N, C, L)
    params = fit_rocket(x, features=840, seed=0)
    with torch.no_grad():
        ours = RocketTransform.from_parameters(params)(torch.as_tensor(x)).numpy()
    cfg, f0 = params.config, 0
    want = np.zeros_like(ours)
    for d, (dil, nf) in enumerate(zip(cfg.dilations, cfg.per_dilation, strict=True)):
        pad = 4 * dil
        for i in range(len(x)):
            conv = (kernel_outputs(x[i], dil) * params.masks[d][:, :, None]).sum(1)  # (84, L) aeon's order
            for k in range(84):
                c = conv[k] if (d + k) % 2 == 0 else conv[k, pad:-pad]
                b = params.biases[f0 + k * nf : f0 + (k + 1) * nf]
                want[i, f0 + k * nf : f0 + (k + 1) * nf] = (c[:, None] > b[None, :]).mean(0)
        f0 += 84 * nf
    np.testing.assert_array_equal(ours, want)


def test_the_sorted_count_and_the_graphs_comparisons_give_the_same_features(monkeypatch) -> None:
    # offline the positions above each bias are counted by sorting; a traced forward (ONNX) compares every pair.
    # The biases are quantiles of these very windows' convolutions, so positions equal to a bias (ties) are many
    rng = np.random.default_rng(3)
    x = on_grid(np.cumsum(rng.normal(size=(12, 4, 70)), axis=2) * 0.3)  # (N, C, L)
    transform = RocketTransform.from_parameters(fit_rocket(x, features=840, seed=1))
    x[0, 1, 30] = np.nan  # a NaN sample (a stream's input) is above no bias either way
    with torch.no_grad():
        sorted_ = transform(torch.as_tensor(x)).numpy()
        monkeypatch.setattr("training.minirocket.rocket_transform._traced", lambda: True)
        compared = transform(torch.as_tensor(x)).numpy()
    np.testing.assert_array_equal(sorted_, compared)
    assert 0.0 < sorted_.mean() < 1.0
