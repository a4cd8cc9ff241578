"""MiniRocket's transform in PyTorch: the fixed kernels at each dilation, summed over each combination's channels,
pooled into the proportion of positions above each bias (PPV). What the family's classifier, its streaming step and
its ONNX graph run.

Per dilation, each kernel's channels are summed first (one matrix product: the convolution is linear), then one
grouped ``conv1d`` applies the 84 nine-tap filters, and every position is compared with every bias: operators ONNX
has, and several times faster than aeon's order of sums written in torch. Checked against aeon's numbers
(``tests/training/test_rocket_transform.py``): equal but where a sum lands within float32 rounding of a bias (1 of
29,988 features there, by one position). The classifier puts its inputs on a grid where every sum is exact
(``rocket_kernels.GRID``), so there the order of sums cannot matter.
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from .rocket_kernels import KERNEL_TAPS, KERNELS, TAPS, RocketConfig, RocketParameters


class RocketTransform(nn.Module):
    """``(B, C, L)`` windows -> ``(B, F)`` MiniRocket features; the masks and biases are buffers (saved, never
    trained)."""

    def __init__(self, config: RocketConfig) -> None:
        super().__init__()
        self.config = config
        d = len(config.dilations)
        self.register_buffer("masks", torch.zeros(d, KERNELS, config.channels))
        self.register_buffer("biases", torch.zeros(config.features))
        weights = -torch.ones(KERNELS, TAPS)
        weights[torch.arange(KERNELS)[:, None], torch.as_tensor(KERNEL_TAPS)] = 2.0
        self.register_buffer("taps", weights[:, None, :], persistent=False)  # (84, 1, 9): -1, 2 at its three taps
        # which positions each (dilation, kernel) pools: all of them, or (every other kernel, as aeon alternates)
        # those whose taps all fall inside the window
        span = torch.arange(config.length)
        valid = []
        for i, dil in enumerate(config.dilations):
            pad = (TAPS - 1) * dil // 2
            inside = ((span >= pad) & (span < config.length - pad)).float()
            rows = [torch.ones(config.length) if (i + k) % 2 == 0 else inside for k in range(KERNELS)]
            valid.append(torch.stack(rows))  # (84, L)
        self.register_buffer("pooled", torch.stack(valid), persistent=False)  # (D, 84, L)

    @classmethod
    def from_parameters(cls, parameters: RocketParameters) -> RocketTransform:
        """The transform of a fit (:func:`.rocket_kernels.fit_rocket`, or aeon's via ``aeon_parameters``)."""
        module = cls(parameters.config)
        module.masks.copy_(torch.as_tensor(parameters.masks))
        module.biases.copy_(torch.as_tensor(parameters.biases))
        return module

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Features of ``x`` ``(B, C, L)``: ``(B, F)`` proportions in [0, 1]."""
        cfg = self.config
        out, f0 = [], 0
        for i, (dil, nf) in enumerate(zip(cfg.dilations, cfg.per_dilation, strict=True)):
            # the convolution is linear: each kernel's channels summed first, then one 9-tap filter per kernel
            mixed = torch.einsum("bcl,kc->bkl", x, self.masks[i])  # (B, 84, L)
            pad = (TAPS - 1) * dil // 2
            conv = F.conv1d(mixed, self.taps, padding=pad, dilation=dil, groups=KERNELS)  # (B, 84, L)
            pooled = self.pooled[i]  # (84, L)
            conv = torch.where(pooled > 0, conv, -torch.inf)  # positions a kernel does not pool never count
            bias = self.biases[f0 : f0 + KERNELS * nf].view(1, KERNELS, 1, nf)
            count = (conv[..., None] > bias).to(x.dtype).sum(2)  # (B, 84, nf) whole numbers: exact in float32
            out.append((count / pooled.sum(1)[None, :, None]).flatten(1))  # (B, 84·nf)
            f0 += KERNELS * nf
        return torch.cat(out, 1)  # (B, F)
