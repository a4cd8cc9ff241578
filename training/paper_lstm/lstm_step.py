"""The paper family one sample at a time as a PyTorch module with explicit state: what the ONNX export traces.

:class:`StepModel` is the one-step computation (stage-1 LSTM cell, features, every ensemble member's LSTM cell, mean
probabilities). The robot's runtime computes the same step with fused weights in NumPy (:mod:`.fused_step`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..training_errors import BundleError
from .lstm_models import stage1_features

if TYPE_CHECKING:
    from ..runtime import ModelBundle

INPUTS = ("x", "h1", "c1", "h2", "c2", "prev", "started")
OUTPUTS = ("probs", "h1_out", "c1_out", "h2_out", "c2_out", "prev_out")
STREAM_AXES = (0, 0, 0, 1, 1, 0, 0)  # per input: the axis that counts streams (h2, c2 are (M, B, H))


def _cell(x: torch.Tensor, h: torch.Tensor, c: torch.Tensor, w_ih, w_hh, b) -> tuple[torch.Tensor, torch.Tensor]:
    """One LSTM step, PyTorch's gate order (i, f, g, o). ``x (B, F)``, ``h, c (B, H)``."""
    gates = x @ w_ih.T + h @ w_hh.T + b  # (B, 4H)
    i, f, g, o = gates.chunk(4, dim=-1)
    c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
    return torch.sigmoid(o) * torch.tanh(c), c


class StepModel(nn.Module):
    """One step of both stages for ``B`` streams; states are explicit inputs and outputs.

    Inputs: ``x (B, C)`` raw sample, ``h1, c1 (B, H1)``, ``h2, c2 (M, B, H2)``, ``prev (B, C)`` stage 1's estimate
    of this sample from the step before (zeros at a stream's start, meaning "no estimate yet").
    Outputs: ``probs (B, K)`` ensemble mean, then the new ``h1, c1, h2, c2, prev``.
    """

    def __init__(self, bundle: ModelBundle) -> None:
        super().__init__()
        if not bundle.classifiers:
            raise BundleError("the bundle has no classifier: train stage 2 first")
        p = bundle.predictor
        self.mode = bundle.feature_mode
        self.register_buffer("mean", torch.from_numpy(bundle.normalizer.mean))
        self.register_buffer("std", torch.from_numpy(bundle.normalizer.std))
        self.register_buffer("w1_ih", p.lstm.weight_ih_l0.detach().clone())
        self.register_buffer("w1_hh", p.lstm.weight_hh_l0.detach().clone())
        self.register_buffer("b1", (p.lstm.bias_ih_l0 + p.lstm.bias_hh_l0).detach().clone())
        self.register_buffer("head_w", p.head.weight.detach().clone())
        self.register_buffer("head_b", p.head.bias.detach().clone())
        cs = bundle.classifiers
        folded = [m.folded_input() for m in cs]  # input standardisation folded into the weights
        self.register_buffer("w2_ih", torch.stack([w for w, _ in folded]))  # (M, 4H, F)
        self.register_buffer("w2_hh", torch.stack([m.lstm.weight_hh_l0.detach() for m in cs]))  # (M, 4H, H)
        self.register_buffer("b2", torch.stack([b for _, b in folded]))  # (M, 4H)
        self.register_buffer("out_w", torch.stack([m.head.weight.detach() for m in cs]))  # (M, K, H)
        self.register_buffer("out_b", torch.stack([m.head.bias.detach() for m in cs]))  # (M, K)

    def forward(self, x, h1, c1, h2, c2, prev, started):
        z = (x - self.mean) / self.std  # (B, C)
        h1, c1 = _cell(z, h1, c1, self.w1_ih, self.w1_hh, self.b1)
        estimate = h1 @ self.head_w.T + self.head_b  # (B, C): estimate of the next sample
        error = (z - prev) * started  # (B, C): zero at a stream's first sample, as offline
        feats = stage1_features(self.mode, h1, estimate, error)  # (B, F): the offline pass's features, one step
        gates = torch.einsum("bf,mgf->mbg", feats, self.w2_ih) + torch.einsum("mbh,mgh->mbg", h2, self.w2_hh)
        gates = gates + self.b2[:, None, :]  # (M, B, 4H)
        i, f, g, o = gates.chunk(4, dim=-1)
        c2 = torch.sigmoid(f) * c2 + torch.sigmoid(i) * torch.tanh(g)
        h2 = torch.sigmoid(o) * torch.tanh(c2)  # (M, B, H)
        logits = torch.einsum("mbh,mkh->mbk", h2, self.out_w) + self.out_b[:, None, :]
        probs = torch.softmax(logits, dim=-1).mean(dim=0)  # (B, K)
        return probs, h1, c1, h2, c2, estimate


def zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``."""
    m, c = len(bundle.classifiers), len(bundle.channels)
    h1, h2 = bundle.predictor.config.hidden, bundle.classifiers[0].config.hidden
    z = np.zeros
    return {
        "h1": z((streams, h1), np.float32),
        "c1": z((streams, h1), np.float32),
        "h2": z((m, streams, h2), np.float32),
        "c2": z((m, streams, h2), np.float32),
        "prev": z((streams, c), np.float32),
        "started": z((streams, 1), np.float32),
    }
