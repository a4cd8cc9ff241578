"""The ensemble's window classifiers as one network: every member's logits and pooled features from one call.

Each member standardises a frame before its 1x1 mixing convolution; folded into the mixing weights (as the streaming
step folds them, ``WindowClassifier.arrays``) the members read the same raw frames, so their mixing is one matrix
product with every member's channels side by side, and the rest (the 3-frame convolution, the pooling, the head)
batched products over the members. The numbers are the members' own to float rounding (tested to 1e-5).
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from torch import nn
from torch.nn import functional as F

from .window_classifier import SPREAD_EPS, WindowClassifier


class StackedWindows(nn.Module):
    """``M`` window classifiers of one config as one module (weights copied; the members are left as they were)."""

    def __init__(self, members: Sequence[WindowClassifier]) -> None:
        super().__init__()
        configs = {(m.config.n_features, m.config.n_classes, m.config.window, m.config.hidden) for m in members}
        if len(configs) != 1:
            raise ValueError(f"members of different sizes cannot be stacked: {sorted(configs)}")
        cfg = members[0].config
        self.m, self.window, self.hidden, self.width = len(members), cfg.window, cfg.hidden, cfg.frame_width
        h = cfg.hidden
        with torch.no_grad():
            mix = torch.stack([m.mix.weight[:, :, 0] * m.in_scale for m in members])  # (M, H, F) standardising folded
            mix_b = torch.stack([m.mix.bias - (m.mix.weight[:, :, 0] * m.in_scale) @ m.in_mean for m in members])
            conv = torch.stack([m.conv.weight.permute(0, 2, 1).reshape(h, 3 * h).T for m in members])  # (M, 3H, H)
            self.register_buffer("mix", mix.permute(2, 0, 1).reshape(cfg.frame_width, -1).contiguous())  # (F, M·H)
            self.register_buffer("mix_b", mix_b.reshape(-1).clone())  # (M·H,)
            self.register_buffer("conv", conv.contiguous())
            self.register_buffer("conv_b", torch.stack([m.conv.bias for m in members])[:, None].clone())  # (M, 1, H)
            self.register_buffer("head", torch.stack([m.head.weight.T for m in members]).contiguous())  # (M, 2H, K)
            self.register_buffer("head_b", torch.stack([m.head.bias for m in members])[:, None].clone())  # (M, 1, K)
            self.register_buffer("in_mean", torch.stack([m.in_mean for m in members]))  # (M, F)
            self.register_buffer("in_scale", torch.stack([m.in_scale for m in members]))  # (M, F)

    def forward(self, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``rows (N, W·F)`` raw stacked frames -> every member's ``logits (M, N, K)`` and pooled features
        ``(M, N, 2H)`` (what its head reads and its drift compares)."""
        n, w, m, h = len(rows), self.window, self.m, self.hidden
        x = F.gelu(F.linear(rows.reshape(n * w, self.width), self.mix.T, self.mix_b), approximate="tanh")  # (N·W, M·H)
        x = x.reshape(n, w, m, h).permute(2, 0, 1, 3)  # (M, N, W, H)
        padded = F.pad(x, (0, 0, 1, 1))  # (M, N, W + 2, H)
        taps = torch.cat([padded[:, :, k : k + w] for k in range(3)], dim=3)  # (M, N, W, 3H): frames t-1, t, t+1
        y = torch.baddbmm(self.conv_b, taps.reshape(m, n * w, 3 * h), self.conv)  # (M, N·W, H)
        y = F.gelu(y, approximate="tanh").reshape(m, n, w, h)  # (M, N, W, H)
        mean = y.mean(dim=2)  # (M, N, H)
        std = ((y - mean[:, :, None]).pow(2).mean(dim=2) + SPREAD_EPS).sqrt()
        pooled = torch.cat([mean, std], dim=2)  # (M, N, 2H)
        return torch.baddbmm(self.head_b, pooled, self.head), pooled  # (M, N, K), (M, N, 2H)

    def inputs_view(self, rows: torch.Tensor) -> torch.Tensor:
        """``rows (N, W·F)`` -> each member's standardised window mean ``(M, N, F)`` (the drift's inputs view)."""
        mean = rows.reshape(len(rows), self.window, self.width).mean(dim=1)  # (N, F) the same for every member
        return (mean[None] - self.in_mean[:, None]) * self.in_scale[:, None]  # (M, N, F)
