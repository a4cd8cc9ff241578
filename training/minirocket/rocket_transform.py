"""MiniRocket's transform in PyTorch: the fixed kernels at each dilation, summed over each combination's channels,
pooled into the proportion of positions above each bias (PPV). What the family's classifier, its streaming step and
its ONNX graph run.

Per dilation, one ``conv1d`` applies the 84 kernels, each its nine taps on its combination of channels (the taps
times the channel mask: the convolution is linear, so this equals summing the channels first and filtering after),
and each kernel's positions above each bias are counted. Offline, the counts come from each kernel's positions
sorted and searched for the biases (NumPy sorts rows of a few hundred floats four times faster than torch on the
CPU); an ONNX graph has no search, so a traced or exported forward compares every position with every bias instead,
which gives the same counts at about six times the cost and memory. Checked against aeon's numbers
(``tests/training/test_rocket_transform.py``): equal but where a sum lands within float32 rounding of a bias (1 of
29,988 features there, by one position). The classifier puts its inputs on a grid where every sum is exact
(``rocket_kernels.GRID``), so there the order of sums cannot matter.
"""

from __future__ import annotations

import numpy as np
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
        traced = _traced()
        out, f0 = [], 0
        for i, (dil, nf) in enumerate(zip(cfg.dilations, cfg.per_dilation, strict=True)):
            weight = self.masks[i][:, :, None] * self.taps  # (84, C, 9): each kernel's taps on its channels
            pad = (TAPS - 1) * dil // 2
            conv = F.conv1d(x, weight, padding=pad, dilation=dil)  # (B, 84, L)
            pooled = self.pooled[i]  # (84, L)
            conv = torch.where(pooled > 0, conv, -torch.inf)  # positions a kernel does not pool never count
            bias = self.biases[f0 : f0 + KERNELS * nf].view(KERNELS, nf)
            count = _count_compared(conv, bias) if traced else _count_sorted(conv, bias)  # (B, 84, nf)
            out.append((count.to(x.dtype) / pooled.sum(1)[None, :, None]).flatten(1))  # (B, 84·nf)
            f0 += KERNELS * nf
        return torch.cat(out, 1)  # (B, F)


def _traced() -> bool:
    """Whether this forward is being traced or exported (to ONNX): only graph operators may run."""
    return bool(
        torch.jit.is_tracing() or torch.onnx.is_in_onnx_export() or torch.compiler.is_compiling()
    )  # fmt: skip


def _count_compared(conv: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """Positions of ``conv (B, 84, L)`` above each of ``bias (84, nf)``: ``(B, 84, nf)``, every pair compared (what
    an ONNX graph can run; a ``(B, 84, L, nf)`` block)."""
    return (conv[..., None] > bias[None, :, None, :]).sum(2)


def _count_sorted(conv: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """As :func:`_count_compared` (the same whole numbers): each row sorted once, each bias searched in it."""
    conv = torch.where(torch.isnan(conv), -torch.inf, conv)  # a NaN is above no bias, as a comparison says; sorted last
    if conv.device.type == "cpu":
        ordered = torch.from_numpy(np.sort(conv.detach().numpy(), axis=-1))  # (B, 84, L)
    else:
        ordered = torch.sort(conv, dim=-1).values
    at_most = torch.searchsorted(ordered, bias.expand(len(conv), *bias.shape).contiguous(), right=True)
    return conv.shape[-1] - at_most  # (B, 84, nf) positions strictly above each bias
