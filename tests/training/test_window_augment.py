"""Run-to-run changes drawn on training rows: each draw changes what it says and nothing else."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from training import RowAugment, SpectralConfig, WindowFitConfig, augment_rows

FRONT = SpectralConfig(frame=8, hop=4, fast=(0, 1), slow=(2,), window=3)  # 5 bins per fast channel, 4 slow stats


def _draw(x: torch.Tensor, augment: RowAugment, *, y: torch.Tensor | None = None, seed: int = 0) -> torch.Tensor:
    y = torch.zeros(len(x), dtype=torch.long) if y is None else y
    mean = torch.full((FRONT.width,), -7.0)
    return augment_rows(x, y, (x, y), FRONT, mean, augment, torch.Generator().manual_seed(seed))


def _frames(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Rows ``(B, W·F)`` -> fast ``(B, W, Cf, bins)`` and slow ``(B, W, Cs, 4)``."""
    f = x.reshape(len(x), FRONT.window, FRONT.width)
    split = len(FRONT.fast) * FRONT.bins
    return f[:, :, :split].reshape(len(x), FRONT.window, -1, FRONT.bins), f[:, :, split:].reshape(
        len(x), FRONT.window, -1, 4
    )


def test_off_by_default() -> None:
    assert not WindowFitConfig().augment.active
    assert RowAugment(mix=0.1).active


def test_gain_adds_one_offset_per_fast_channel_and_row() -> None:
    x = torch.randn(64, FRONT.step_width)
    fast0, slow0 = _frames(x)
    fast1, slow1 = _frames(_draw(x, RowAugment(gain=0.5)))
    shift = fast1 - fast0  # (B, W, Cf, bins)
    assert torch.allclose(shift, shift[:, :1, :, :1].expand_as(shift), atol=1e-5)  # same in every frame and bin
    assert shift[:, 0, :, 0].std() > 0.3  # drawn per row and channel
    assert torch.equal(slow0, slow1)


def test_tilt_is_a_slope_across_bins() -> None:
    x = torch.randn(32, FRONT.step_width)
    fast0, _ = _frames(x)
    fast1, _ = _frames(_draw(x, RowAugment(tilt=1.0)))
    shift = fast1 - fast0
    steps = shift.diff(dim=3)  # (B, W, Cf, bins - 1): one step per bin
    assert torch.allclose(steps, steps[..., :1].expand_as(steps), atol=1e-5)
    assert torch.allclose(shift.sum(dim=3), torch.zeros(()), atol=1e-4)  # centred: the mean level is kept


def test_warp_moves_a_peak_along_the_bins_both_ways() -> None:
    x = torch.zeros(200, FRONT.step_width)
    fast, slow = _frames(x)
    fast[:, :, :, 2] = 1.0  # every frame peaks in the middle bin
    x = torch.cat([fast.flatten(2), slow.flatten(2)], dim=2).flatten(1)
    fast1, slow1 = _frames(_draw(x, RowAugment(warp=0.5)))
    peak = (fast1 * torch.arange(FRONT.bins)).sum(3) / fast1.sum(3).clamp(min=1e-6)  # (B, W, Cf) centre of mass
    assert (peak > 2.2).any() and (peak < 1.8).any()  # faster and slower gaits
    assert torch.allclose(peak, peak[:, :1].expand_as(peak))  # one scale per row and channel, all frames
    assert fast1.max() <= 1.0 + 1e-6 and fast1.min() >= 0.0  # read between bins, never beyond their values
    assert torch.equal(slow1, torch.zeros_like(slow1))


def test_level_shifts_slow_levels_not_their_spread() -> None:
    x = torch.randn(32, FRONT.step_width)
    fast0, slow0 = _frames(x)
    fast1, slow1 = _frames(_draw(x, RowAugment(level=1.0)))
    shift = slow1 - slow0  # (B, W, Cs, 4)
    assert torch.equal(fast0, fast1)
    assert torch.allclose(shift[..., 1], torch.zeros(()))  # the spread
    assert torch.allclose(shift[..., 0], shift[..., 2], atol=1e-5) and torch.allclose(shift[..., 0], shift[..., 3])
    assert shift[..., 0].abs().mean() > 0.3


def test_drop_replaces_whole_channels_by_their_mean_never_all() -> None:
    x = torch.randn(400, FRONT.step_width)
    fast, slow = _frames(_draw(x, RowAugment(drop=0.5)))
    gone_fast = (fast == -7.0).all(dim=3).all(dim=1)  # (B, Cf)
    gone_slow = (slow == -7.0).all(dim=3).all(dim=1)  # (B, Cs)
    gone = torch.cat([gone_fast, gone_slow], dim=1)  # (B, C)
    assert 0.35 < gone.float().mean() < 0.6
    assert not gone.all(dim=1).any()
    # a channel goes whole or not at all: every mean-valued feature belongs to a channel that went
    dropped_features = int((fast == -7.0).sum() + (slow == -7.0).sum())
    assert dropped_features == int((gone_fast.sum() * FRONT.bins + gone_slow.sum() * 4) * FRONT.window)


def test_mix_stays_inside_its_terrain() -> None:
    y = torch.tensor([0, 1] * 50)
    x = torch.where(y[:, None] == 0, 0.0, 1.0 + 2.0 * torch.rand(100, 1)).expand(100, FRONT.step_width).clone()
    out = _draw(x, RowAugment(mix=1.0), y=y)
    assert torch.equal(out[y == 0], x[y == 0])  # terrain 0's rows only ever meet terrain 0's
    ones = out[y == 1]
    assert ones.min() >= 1.0 and ones.max() <= 3.0
    assert not torch.equal(ones, x[y == 1])


@pytest.mark.parametrize("augment", [RowAugment(gain=0.3, warp=0.1, drop=0.2, mix=0.5, level=0.3, tilt=0.3)])
def test_all_draws_keep_shape_and_are_seeded(augment: RowAugment) -> None:
    x = torch.randn(16, FRONT.step_width)
    a, b = _draw(x, augment, seed=3), _draw(x, augment, seed=3)
    assert a.shape == x.shape and torch.equal(a, b)
    assert np.isfinite(a.numpy()).all()
