"""What changes between runs, drawn on the training rows: screened for the default family on held-out runs.

A run differs from another of the same terrain by its sensors' gains and offsets, the robot's speed (which shifts
vibration in frequency) and which channels carry the terrain. Each field of :class:`.window_config.RowAugment` draws
one such change per training row, on the raw frame features (log power spectra of the fast channels, level
statistics of the slow ones, the layout of :class:`.spectra.SpectralConfig`), before the network standardises them.
All are off by default: none earned its place on BorealTC's inner folds by run (``benchmarks/runs_screen.py`` at
38a27ac).
"""

from __future__ import annotations

import torch

from .spectra import SpectralConfig
from .window_config import RowAugment


def augment_rows(
    x: torch.Tensor,
    y: torch.Tensor,
    pool: tuple[torch.Tensor, torch.Tensor],
    front: SpectralConfig,
    mean: torch.Tensor,
    augment: RowAugment,
    gen: torch.Generator,
) -> torch.Tensor:
    """Rows ``x (B, W·F)`` of classes ``y (B,)`` with the changes of ``augment`` drawn on each.

    Args:
        x: Raw step rows (``window`` frames, oldest first).
        y: Their classes.
        pool: Every training row and its class ``(N, W·F), (N,)``: where a mixed row's partner is drawn.
        front: The frames' layout.
        mean: ``(F,)`` each frame feature's mean: what a dropped channel becomes.
        augment: Which changes and how large.
        gen: The fit's generator.
    """
    b, w = len(x), front.window
    n_fast, bins, n_slow = len(front.fast), front.bins, len(front.slow)
    split = n_fast * bins
    x = x.reshape(b, w, front.width).clone()  # (B, W, F)
    if augment.mix > 0:
        px, py = pool
        partner = _same_class(y, py, gen)  # (B,)
        lam = torch.rand(b, generator=gen)
        lam = torch.where(torch.rand(b, generator=gen) < augment.mix, lam, torch.ones(b))[:, None, None]
        x = lam * x + (1 - lam) * px[partner].reshape(b, w, front.width)
    if n_fast:
        fast = x[:, :, :split].reshape(b, w, n_fast, bins)  # (B, W, Cf, bins)
        if augment.warp > 0:
            scale = torch.exp(torch.randn(b, 1, n_fast, 1, generator=gen) * augment.warp)
            pos = (torch.arange(bins, dtype=x.dtype) / scale).clamp(0, bins - 1)  # (B, 1, Cf, bins)
            lo = pos.floor().long()
            hi = (lo + 1).clamp(max=bins - 1)
            frac = pos - lo
            lo, hi = lo.expand(b, w, n_fast, bins), hi.expand(b, w, n_fast, bins)
            fast = fast.gather(3, lo) * (1 - frac) + fast.gather(3, hi) * frac
        if augment.gain > 0:
            fast = fast + torch.randn(b, 1, n_fast, 1, generator=gen) * augment.gain
        if augment.tilt > 0:
            ramp = torch.linspace(-1.0, 1.0, bins)  # (bins,)
            fast = fast + torch.randn(b, 1, n_fast, 1, generator=gen) * augment.tilt * ramp
        x = torch.cat([fast.reshape(b, w, split), x[:, :, split:]], dim=2)
    if n_slow and augment.level > 0:
        slow = x[:, :, split:].reshape(b, w, n_slow, 4)  # (B, W, Cs, [mean, spread, min, max])
        shift = torch.randn(b, 1, n_slow, 1, generator=gen) * augment.level
        slow = slow + shift * torch.tensor([1.0, 0.0, 1.0, 1.0])
        x = torch.cat([x[:, :, :split], slow.reshape(b, w, 4 * n_slow)], dim=2)
    if augment.drop > 0:
        channel_of = torch.cat(
            [torch.arange(n_fast).repeat_interleave(bins), n_fast + torch.arange(n_slow).repeat_interleave(4)]
        )  # (F,) the channel of each frame feature
        dropped = torch.rand(b, n_fast + n_slow, generator=gen) < augment.drop  # (B, C)
        keep_all = dropped.all(dim=1)  # a row with every channel dropped carries nothing: keep it whole
        dropped[keep_all] = False
        mask = dropped[:, channel_of][:, None, :]  # (B, 1, F)
        x = torch.where(mask, mean, x)
    return x.reshape(b, w * front.width)


def _same_class(y: torch.Tensor, pool_y: torch.Tensor, gen: torch.Generator) -> torch.Tensor:
    """For each class in ``y (B,)`` the index of a random row of ``pool_y`` with that class."""
    order = torch.argsort(pool_y, stable=True)
    counts = torch.bincount(pool_y, minlength=int(max(y.max(), pool_y.max())) + 1)
    starts = torch.cumsum(counts, 0) - counts
    pick = (torch.rand(len(y), generator=gen) * counts[y]).long().clamp(max=(counts[y] - 1).clamp(min=0))
    return order[starts[y] + pick]
