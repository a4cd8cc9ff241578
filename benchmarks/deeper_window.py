"""Issue 54, item 1's depth screen: the default family's network with more 3-frame convolutions.

``deeper(extra)`` is a :class:`training.WindowClassifier` with ``extra`` residual 3-frame convolutions (each
``x + GELU(conv(x))``, ``hidden`` channels) after its own, before the mean and spread over the window; with
``extra = 0`` it is the shipped network. The first layers draw the same initial weights as the shipped network's (the
extra ones are drawn after them), so a row differs only by the layers it adds. Only the offline protocol runs it: the
streaming step and ONNX export know the shipped network alone, so a depth that earned its place would be written into
``WindowClassifierConfig`` and both of them.

Used by ``benchmarks/minirocket_borealtc.py --depth D`` (the network's convolutions: 2 shipped, 3 or more screened).
"""

from __future__ import annotations

import torch
from torch import nn
from torch.nn import functional as F

from training import WindowClassifier, WindowClassifierConfig


def deeper(extra: int) -> type[WindowClassifier]:
    """The window classifier with ``extra`` more residual 3-frame convolutions (a class built from a config alone,
    as the fit builds the shipped one)."""

    class DeeperWindowClassifier(WindowClassifier):
        def __init__(self, config: WindowClassifierConfig) -> None:
            super().__init__(config)
            h = config.hidden
            self.deep = nn.ModuleList(nn.Conv1d(h, h, 3, padding=1) for _ in range(extra))

        def convolved(
            self, frames: torch.Tensor, *, keep: torch.Tensor | None = None, generator: torch.Generator | None = None
        ) -> torch.Tensor:
            x = super().convolved(frames, keep=keep, generator=generator)  # (N, W, H)
            for conv in self.deep:
                # residual, so an extra layer starts near the shipped network's function
                x = x + F.gelu(conv(x.transpose(1, 2)).transpose(1, 2), approximate="tanh")  # (N, W, H)
            return x

    return DeeperWindowClassifier
