"""The two stages as modules: a config dataclass plus an ``nn.Module`` each (as nanoGPT does)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from .lstm_config import ClassifierConfig, FeatureMode, PredictorConfig

State = tuple[torch.Tensor, torch.Tensor]  # (h, c), each (1, B, H)


class Predictor(nn.Module):
    """Stage 1: ``h_t = LSTM(x_≤t)``, ``x̂_{t+1} = W h_t + b``."""

    def __init__(self, config: PredictorConfig) -> None:
        super().__init__()
        self.config = config
        self.lstm = nn.LSTM(config.n_channels, config.hidden, batch_first=True)
        self.head = nn.Linear(config.hidden, config.n_channels)

    def forward(self, x: torch.Tensor, state: State | None = None) -> tuple[torch.Tensor, torch.Tensor, State]:
        """Run over normalised samples.

        Args:
            x: ``(B, T, C)``.
            state: Carried ``(h, c)`` or None for zeros.

        Returns:
            ``estimate (B, T, C)`` where ``estimate[:, t]`` is the estimate of ``x[:, t + 1]``; the hidden states
            ``(B, T, H)``; the final state.
        """
        hidden, state = self.lstm(x, state)  # (B, T, H)
        return self.head(hidden), hidden, state


def stage1_features(
    mode: FeatureMode, hidden: torch.Tensor, estimate: torch.Tensor, error: torch.Tensor
) -> torch.Tensor:
    """What stage 2 sees at each timestep, all causal at ``t``.

    Args:
        mode: Which of stage 1's outputs to use.
        hidden: ``(B, T, H)`` hidden state after ``x_t``.
        estimate: ``(B, T, C)`` estimate of ``x_{t+1}``.
        error: ``(B, T, C)`` ``x_t − x̂_t`` (zero at a sequence's first step, which has no estimate).

    ``surprise`` is ``|x_t − x̂_t|`` per channel: how much of each signal stage 1 could not predict. Terrain shows
    in the size of that residual (roughness, slip, vibration) more than in its sign, and a classifier trained on a
    few labels learns it far better from the magnitude than from the signed error or the hidden state alone
    (held-out demo logs, 40 labelled 3 s segments: 64 % against 44 % and 31 %). ``hidden+surprise``, the
    workbench's default, keeps the hidden state beside it, which is what BorealTC's few-label runs liked best
    (benchmarks/results/raw/protocols/notebook-label-efficiency-2026-11-26.md).
    """
    if mode == "hidden":
        return hidden
    if mode == "estimate":
        return estimate
    if mode == "error":
        return error
    if mode == "surprise":
        return error.abs()
    if mode == "hidden+surprise":
        return torch.cat([hidden, error.abs()], dim=-1)  # (B, T, H + C)
    return torch.cat([hidden, error], dim=-1)  # (B, T, H + C)


def feature_width(mode: FeatureMode, hidden: int, channels: int) -> int:
    """``F`` of ``stage1_features(mode, ...)`` for a stage 1 of ``hidden`` units over ``channels`` channels."""
    return {"hidden": hidden, "hidden+surprise": hidden + channels, "hidden+error": hidden + channels}.get(
        mode, channels
    )


class Classifier(nn.Module):
    """Stage 2: standardise, dropout, LSTM, dropout, linear, softmax (softmax applied by the loss / at inference).

    The standardisation (``in_mean``, ``in_scale``, buffers saved with the weights) puts every stage-1 feature on
    unit variance over the logs it was fitted on, so no feature dominates the first products by its scale alone;
    the streaming runtime folds it into the LSTM's input weights.
    """

    def __init__(self, config: ClassifierConfig) -> None:
        super().__init__()
        self.config = config
        self.register_buffer("in_mean", torch.zeros(config.n_features))
        self.register_buffer("in_scale", torch.ones(config.n_features))
        self.drop_in = nn.Dropout(config.dropout)  # the 20 % dropout after stage 1's LSTM layer
        self.lstm = nn.LSTM(config.n_features, config.hidden, batch_first=True)
        self.drop_out = nn.Dropout(config.dropout)  # and after this one
        self.head = nn.Linear(config.hidden, config.n_classes)

    def forward(self, features: torch.Tensor, state: State | None = None) -> tuple[torch.Tensor, State]:
        """``features (B, T, F)`` -> ``logits (B, T, K)`` and the final state."""
        z = (features - self.in_mean) * self.in_scale  # (B, T, F)
        out, state = self.lstm(self.drop_in(z), state)  # (B, T, H)
        return self.head(self.drop_out(out)), state

    def set_standardisation(self, mean: np.ndarray, std: np.ndarray) -> None:
        """Standardise inputs with per-feature ``mean`` and ``std`` ``(F,)`` (features with no spread are centred)."""
        std = np.where(std > 1e-8, std, 1.0)
        self.in_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
        self.in_scale.copy_(torch.as_tensor(1.0 / std, dtype=torch.float32))

    def folded_input(self) -> tuple[torch.Tensor, torch.Tensor]:
        """The LSTM's input weights ``(4H, F)`` and summed biases ``(4H,)`` with the standardisation folded in."""
        w = self.lstm.weight_ih_l0.detach() * self.in_scale  # (4H, F)
        b = (self.lstm.bias_ih_l0 + self.lstm.bias_hh_l0).detach() - w @ self.in_mean
        return w, b


def feature_moments(features: Sequence[np.ndarray], *, chunk: int = 1 << 16) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and standard deviation ``(F,)`` over every step of ``features`` (each ``(T, F)``, or
    anything sliced like it: a chunk is read at a time, so memory-mapped or lazy features stay on disk)."""

    def chunks():
        for f in features:
            for a in range(0, len(f), chunk):
                yield np.asarray(f[a : a + chunk], np.float64)

    n = sum(len(f) for f in features)
    mean = sum((x.sum(0) for x in chunks()), np.zeros(features[0].shape[1])) / max(n, 1)
    var = sum((np.square(x - mean).sum(0) for x in chunks()), np.zeros(len(mean))) / max(n, 1)
    return mean.astype(np.float32), np.sqrt(var).astype(np.float32)
