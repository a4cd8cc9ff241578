"""The default family's window network: its matrix-product convolutions and the draws of its fits."""

from __future__ import annotations

import numpy as np
import torch
from torch.nn import functional as F

from training.spectral_cnn.row_draws import RowDraws
from training.spectral_cnn.window_classifier import SPREAD_EPS, WindowClassifier, WindowClassifierConfig


def _conv1d_logits(model: WindowClassifier, windows: torch.Tensor) -> torch.Tensor:
    """The network as ``Conv1d`` modules compute it on ``(N, F, W)``: what the matrix products must equal."""
    x = model.standardise(windows).transpose(1, 2)  # (N, F, W)
    h = F.gelu(model.conv(F.gelu(model.mix(x), approximate="tanh")), approximate="tanh")  # (N, H, W)
    mean = h.mean(dim=2)
    std = ((h - mean[:, :, None]).pow(2).mean(dim=2) + SPREAD_EPS).sqrt()
    return model.head(torch.cat([mean, std], dim=1))


def test_the_matrix_product_convolutions_give_conv1d_numbers_and_gradients() -> None:
    torch.manual_seed(0)
    model = WindowClassifier(WindowClassifierConfig(7 * 12, 4, window=7, hidden=16)).eval()
    model.set_standardisation(np.linspace(-1, 1, 12), np.linspace(0.5, 2, 12))
    windows = torch.randn(50, 7 * 12)
    ours, theirs = model.logits(windows), _conv1d_logits(model, windows)
    assert torch.allclose(ours, theirs, atol=1e-5), (ours - theirs).abs().max()
    grads = []
    for fn in (model.logits, lambda w: _conv1d_logits(model, w)):
        model.zero_grad()
        fn(windows).square().sum().backward()
        grads.append([p.grad.clone() for p in (model.mix.weight, model.conv.weight, model.conv.bias)])
    for a, b in zip(*grads, strict=True):
        assert torch.allclose(a, b, atol=1e-4), (a - b).abs().max()


def test_dropout_while_training_uses_the_mask_given_and_scales_the_kept_values() -> None:
    torch.manual_seed(0)
    model = WindowClassifier(WindowClassifierConfig(7 * 12, 4, window=7, hidden=16, dropout=0.25))
    frames = torch.randn(8, 7, 12)
    keep = torch.rand(8, 7, 12) >= 0.25
    model.train()
    trained = model.frame_logits(frames, keep=keep)
    model.eval()
    expected = model.frame_logits(frames * keep / 0.75)  # dropout as F.dropout applies it
    assert torch.allclose(trained, expected, atol=1e-5)
    assert torch.equal(model.frame_logits(frames), model.frame_logits(frames, keep=keep))  # no dropout in eval


def test_row_draws_are_standard_normal_noise_and_a_mask_of_one_minus_p_each_seed_its_own() -> None:
    draws = RowDraws(3, dropout=0.2)
    noise, keep = draws((400, 7, 50))
    assert noise.shape == keep.shape == (400, 7, 50) and noise.dtype == torch.float32 and keep.dtype == torch.bool
    assert abs(noise.mean().item()) < 0.01 and abs(noise.std().item() - 1.0) < 0.01
    assert abs(float((noise.abs() > 1.96).float().mean()) - 0.05) < 0.003  # normal tails, not a uniform's
    assert abs(keep.float().mean().item() - 0.8) < 0.005
    assert abs(np.corrcoef(noise.flatten().numpy(), keep.flatten().numpy())[0, 1]) < 0.01  # independent draws
    again, _ = RowDraws(3, dropout=0.2)((400, 7, 50))
    other, _ = RowDraws(4, dropout=0.2)((400, 7, 50))
    assert torch.equal(noise, again) and not torch.equal(noise, other)
    odd, odd_keep = draws((3, 1, 5))  # an odd count still gets two numbers per value
    assert odd.shape == odd_keep.shape == (3, 1, 5)
