"""The default family's stage 2: a linear softmax on a step's spectral window summary (config dataclass + module).

Each step's input is the mean and spread of the last few short-time spectra (``spectral.SpectralSteps``), so the
model needs no state: a step's probabilities depend on its input alone, and the passes, the streaming runtime and
the ONNX model all compute ``softmax(W · standardise(f) + b)``. It has the paper classifier's call signature
(features and a state in, logits and a state out; the state is always ``None``), so the offline passes run both.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

WINDOW_KIND = "window"  # the ``kind`` in a bundle's classifier config that names this module


@dataclass(frozen=True)
class WindowClassifierConfig:
    """Sizes of the window classifier.

    Attributes:
        n_features: Inputs per step (``SpectralConfig.summary_width``).
        n_classes: Terrains.
        kind: Always ``"window"``: tells a bundle's config which module to rebuild.
    """

    n_features: int
    n_classes: int
    kind: str = WINDOW_KIND


class WindowClassifier(nn.Module):
    """Standardise, linear, softmax (applied by the caller), on each step on its own."""

    def __init__(self, config: WindowClassifierConfig) -> None:
        super().__init__()
        self.config = config
        self.register_buffer("in_mean", torch.zeros(config.n_features))
        self.register_buffer("in_scale", torch.ones(config.n_features))
        self.head = nn.Linear(config.n_features, config.n_classes)

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, F)`` -> ``logits (B, T, K)``; no state is carried."""
        return self.head((features - self.in_mean) * self.in_scale), None

    def set_standardisation(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Standardise inputs with per-feature ``mean`` and ``std`` ``(F,)`` (features with no spread are centred)."""
        std = np.where(std > 1e-8, std, 1.0)
        self.in_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.in_scale.copy_(torch.as_tensor(1.0 / std, dtype=torch.float32))

    def set_linear(self, weight: np.ndarray, bias: np.ndarray) -> None:
        """The head's ``(K, F)`` weights and ``(K,)`` bias, on standardised inputs."""
        with torch.no_grad():
            self.head.weight.copy_(torch.as_tensor(weight, dtype=torch.float32))
            self.head.bias.copy_(torch.as_tensor(bias, dtype=torch.float32))

    def folded(self) -> tuple[np.ndarray, np.ndarray]:
        """``(F, K)`` weights and ``(K,)`` bias on raw inputs, the standardisation folded in (the runtime's)."""
        w = (self.head.weight.detach() * self.in_scale).numpy()  # (K, F)
        b = (self.head.bias.detach() - torch.as_tensor(w) @ self.in_mean).numpy()  # (K,)
        return np.ascontiguousarray(w.T, np.float32), b.astype(np.float32)
