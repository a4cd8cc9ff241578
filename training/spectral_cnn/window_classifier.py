"""The default family's stage 2: a small convolutional network over a step's last few spectral frames (config
dataclass + module).

Each step's input is the last ``window`` short-time frames (``spectral.SpectralSteps``), oldest first. Each frame is
standardised and mixed by a 1x1 convolution (which bins of which channels matter), a 3-frame convolution follows,
and the mean and spread of its outputs over the window feed a linear head: BorealTC's CNN reads spectrograms the
same way. On BorealTC's inner folds it beat a linear model (and a one-layer MLP) on the frames' mean and spread by
4 to 6 points at 10 % of labels (``benchmarks/studies/default_family_cnn.py``).

The model keeps no state: a step's probabilities depend on its input alone. It has the paper classifier's call
signature (features and a state in, logits and a state out; the state is always ``None``), so the offline passes run
both families. GELU is the tanh form so the NumPy passes (:mod:`.frame_numpy`, the streaming step) compute the same
numbers without ``erf``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from ..passes import per_distinct_row
from .frame_numpy import SPREAD_EPS
from .kinds import WINDOW_KIND


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

    def logits(self, windows: torch.Tensor, *, generator: torch.Generator | None = None) -> torch.Tensor:
        """``windows (N, W·F)`` -> ``logits (N, K)``; ``generator`` draws the dropout while training."""
        return self.frame_logits(self.standardise(windows), generator=generator)

    def frame_logits(
        self, frames: torch.Tensor, *, keep: torch.Tensor | None = None, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Standardised ``frames (N, W, F)`` -> ``logits (N, K)`` (see :meth:`pooled`)."""
        return self.head(self.pooled(frames, keep=keep, generator=generator))  # (N, K)

    def embedding(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, W·F)`` -> the pooled features the head reads, ``(N, 2H)``: what the drift score compares."""
        return self.pooled(self.standardise(windows))  # (N, 2H)

    def standardise(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, W·F)`` -> each frame standardised, ``(N, W, F)``."""
        x = windows.unflatten(1, (self.config.window, self.config.frame_width))  # (N, W, F)
        return (x - self.in_mean) * self.in_scale

    def pooled(
        self, frames: torch.Tensor, *, keep: torch.Tensor | None = None, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Standardised ``frames (N, W, F)`` -> the pooled features ``(N, 2H)``: the mean and spread over the window
        of both convolutions' outputs (:meth:`mixed`, :meth:`windowed`, :meth:`pool`)."""
        return self.pool(self.windowed(self.mixed(frames, keep=keep, generator=generator)))  # (N, 2H)

    def pool(self, x: torch.Tensor) -> torch.Tensor:
        """Both convolutions' outputs ``x (N, W, H)`` -> their mean and spread over the window ``(N, 2H)``."""
        mean = x.mean(dim=1)  # (N, H)
        std = ((x - mean[:, None]).pow(2).mean(dim=1) + SPREAD_EPS).sqrt()  # finite gradient at no spread
        return torch.cat([mean, std], dim=1)  # (N, 2H)

    def mixed(
        self, frames: torch.Tensor, *, keep: torch.Tensor | None = None, generator: torch.Generator | None = None
    ) -> torch.Tensor:
        """Standardised frames ``(..., F)`` -> the 1x1 convolution's outputs ``(..., H)``: each frame on its own, so
        a log's frames can go through it once rather than once per window they sit in. While training, dropout on
        the frames: the values ``keep`` (the frames' shape) holds ``True`` for kept, or a mask drawn from
        ``generator`` (default: torch's global one)."""
        mix = self.mix.weight[:, :, 0]  # (H, F)
        p = self.config.dropout
        if self.training and p > 0.0:
            # dropout's 1 / (1 - p) on the mixing weights, (H, F), rather than on every frame value, (N, W, F)
            frames = frames * (_kept(frames, p, generator) if keep is None else keep)
            mix = mix * (1.0 / (1.0 - p))
        return F.gelu(F.linear(frames, mix, self.mix.bias), approximate="tanh")  # (..., H)

    def windowed(self, x: torch.Tensor) -> torch.Tensor:
        """The 1x1 convolution's outputs over a window ``x (N, W, H)`` -> the 3-frame convolution's ``(N, W, H)``.

        It runs as a matrix product over the window's frames (each frame and its two neighbours side by side, zero
        beyond the window's ends, as ``padding=1``): the same numbers as ``Conv1d`` on ``(N, H, W)`` with the same
        weights, in 0.68 of the time forward and backward on a CPU (a 128 × 7 × 220 batch, one thread), where seven
        frames are too few for a convolution kernel.
        """
        w, h = self.config.window, self.config.hidden
        padded = F.pad(x, (0, 0, 1, 1))  # (N, W + 2, H)
        taps = torch.cat([padded[:, k : k + w] for k in range(3)], dim=2)  # (N, W, 3H): frames t-1, t, t+1
        conv = self.conv.weight.permute(0, 2, 1).reshape(h, 3 * h)  # (H, 3H) tap-major, as ``taps``
        return F.gelu(F.linear(taps, conv, self.conv.bias), approximate="tanh")  # (N, W, H)

    per_row = True  # a step's logits read its own row alone: an ensemble pass asks ``logits`` of distinct rows only

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, W·F)`` -> ``logits (B, T, K)``; no state is carried.

        A step's input changes only when a frame completes (every ``hop`` steps), so the network runs once per
        distinct consecutive row and the result is repeated: twenty times less work at 100 Hz.
        """
        return per_distinct_row(self.logits, features), None

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


def _kept(x: torch.Tensor, p: float, generator: torch.Generator | None) -> torch.Tensor:
    """Dropout's mask, ``x``'s shape: a uniform number against ``p``, the distribution of ``F.dropout``, whose
    Bernoulli sampler is 2.4 times slower on a CPU (a 128 × 7 × 220 batch: 1.14 ms against 0.48). A fit draws its
    masks itself (:mod:`.row_draws`); this one serves a caller that trains the module on its own."""
    return torch.rand(x.shape, device=x.device, generator=generator) >= p  # (N, W, F)
