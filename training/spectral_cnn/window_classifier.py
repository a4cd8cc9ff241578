"""The default family's stage 2: a small convolutional network over a step's last few spectral frames (config
dataclass + module).

Each step's input is the last ``window`` short-time frames (``spectral.SpectralSteps``), oldest first. Each frame is
standardised and mixed by a 1x1 convolution (which bins of which channels matter), a 3-frame convolution follows,
and the mean and spread of its outputs over the window feed a linear head: BorealTC's CNN reads spectrograms the
same way. On BorealTC's inner folds it beat a linear model (and a one-layer MLP) on the frames' mean and spread by
4 to 6 points at 10 % of labels (``benchmarks/default_family_cnn.py``).

The model keeps no state: a step's probabilities depend on its input alone. It has the paper classifier's call
signature (features and a state in, logits and a state out; the state is always ``None``), so the offline passes run
both families. GELU is the tanh form so the NumPy streaming step computes the same numbers without ``erf``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

WINDOW_KIND = "frames"  # the ``kind`` in a bundle's classifier config that names this module
SPREAD_EPS = 1e-6  # added to the pooled variance: a window of identical frames (a log's start) has none
OLD_WINDOW_KINDS = ("window",)  # the linear model on summaries that preceded it: refused with a hint to retrain


@dataclass(frozen=True)
class WindowClassifierConfig:
    """Sizes of the window classifier.

    Attributes:
        n_features: Inputs per step (``SpectralConfig.step_width``: ``window`` frames of ``n_features // window``).
        n_classes: Terrains.
        window: Frames per step.
        hidden: Channels of both convolutions.
        dropout: Dropout on the standardised frames while training.
        kind: Always ``"frames"``: tells a bundle's config which module to rebuild.
    """

    n_features: int
    n_classes: int
    window: int = 7
    hidden: int = 64
    dropout: float = 0.2
    kind: str = WINDOW_KIND

    @property
    def frame_width(self) -> int:
        """Features per frame."""
        return self.n_features // self.window


class WindowClassifier(nn.Module):
    """Standardise each frame, 1x1 conv, GELU, 3-frame conv, GELU, mean and spread over the window, linear."""

    def __init__(self, config: WindowClassifierConfig) -> None:
        super().__init__()
        if config.n_features % config.window:
            raise ValueError(f"n_features {config.n_features} is not a whole number of {config.window} frames")
        self.config = config
        f, h = config.frame_width, config.hidden
        self.register_buffer("in_mean", torch.zeros(f))
        self.register_buffer("in_scale", torch.ones(f))
        self.mix = nn.Conv1d(f, h, 1)
        self.conv = nn.Conv1d(h, h, 3, padding=1)
        self.head = nn.Linear(2 * h, config.n_classes)

    def logits(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, W·F)`` -> ``logits (N, K)``."""
        return self.head(self.embedding(windows))  # (N, K)

    def embedding(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, W·F)`` -> the pooled features the head reads, ``(N, 2H)``: what the drift score compares."""
        cfg = self.config
        x = windows.unflatten(1, (cfg.window, cfg.frame_width))  # (N, W, F)
        x = _dropout((x - self.in_mean) * self.in_scale, cfg.dropout, self.training).transpose(1, 2)  # (N, F, W)
        h = F.gelu(self.mix(x), approximate="tanh")  # (N, H, W)
        h = F.gelu(self.conv(h), approximate="tanh")  # (N, H, W)
        mean = h.mean(dim=2)  # (N, H)
        std = ((h - mean[:, :, None]).pow(2).mean(dim=2) + SPREAD_EPS).sqrt()  # finite gradient at no spread
        return torch.cat([mean, std], dim=1)  # (N, 2H)

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, W·F)`` -> ``logits (B, T, K)``; no state is carried.

        A step's input changes only when a frame completes (every ``hop`` steps), so the network runs once per
        distinct consecutive row and the result is repeated: twenty times less work at 100 Hz.
        """
        b, t, d = features.shape
        flat = features.reshape(b * t, d)  # (B·T, D)
        new = torch.ones(b * t, dtype=torch.bool, device=flat.device)
        new[1:] = (flat[1:] != flat[:-1]).any(dim=1)
        which = torch.cumsum(new.long(), 0) - 1  # (B·T,) index of each row's distinct run
        return self.logits(flat[new])[which].reshape(b, t, -1), None

    def set_standardisation(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Standardise each frame's features with ``mean`` and ``std`` ``(F,)`` (features with no spread centred)."""
        std = np.where(std > 1e-8, std, 1.0)
        self.in_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.in_scale.copy_(torch.as_tensor(1.0 / std, dtype=torch.float32))

    def arrays(self) -> dict[str, np.ndarray]:
        """The weights as float32 arrays for the NumPy streaming step: the standardisation folded into ``mix``.

        ``mix (F, H)``, ``mix_b (H,)``, ``conv (3, H, H)`` (tap, in, out), ``conv_b (H,)``, ``head (2H, K)``,
        ``head_b (K,)``.
        """
        mix = self.mix.weight.detach()[:, :, 0] * self.in_scale  # (H, F)
        mix_b = self.mix.bias.detach() - mix @ self.in_mean
        return {
            "mix": mix.T.contiguous().numpy(),
            "mix_b": mix_b.numpy(),
            "conv": self.conv.weight.detach().permute(2, 1, 0).contiguous().numpy(),
            "conv_b": self.conv.bias.detach().numpy(),
            "head": self.head.weight.detach().T.contiguous().numpy(),
            "head_b": self.head.bias.detach().numpy(),
        }


def _dropout(x: torch.Tensor, p: float, training: bool) -> torch.Tensor:
    """Dropout drawn as a uniform number against ``p``: the distribution of ``F.dropout``, whose Bernoulli sampler
    is 2.4 times slower on a CPU (a 128 × 7 × 220 batch: 1.14 ms against 0.48), and the input's dropout was over a
    third of a fit's time."""
    if not training or p <= 0.0:
        return x
    keep = torch.rand(x.shape, device=x.device) >= p  # (N, W, F)
    return x * keep * (1.0 / (1.0 - p))


def gelu_tanh(x: np.ndarray) -> np.ndarray:
    """PyTorch's ``gelu(x, approximate="tanh")`` in NumPy, float32, in one scratch array (the streaming step calls it
    on small arrays, where each temporary costs as much as the arithmetic)."""
    out = x * x
    out *= x
    out *= np.float32(0.044715)
    out += x
    out *= np.float32(0.7978845608028654)
    np.tanh(out, out=out)
    out += np.float32(1.0)
    out *= x
    out *= np.float32(0.5)
    return out
