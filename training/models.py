"""The two stages as modules: a config dataclass plus an ``nn.Module`` each (as nanoGPT does)."""

from __future__ import annotations

import torch
from torch import nn

from .config import ClassifierConfig, FeatureMode, PredictorConfig

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


def feature_size(mode: FeatureMode, config: PredictorConfig) -> int:
    """Width of the features stage 1 hands stage 2 in ``mode``."""
    return {
        "hidden": config.hidden,
        "estimate": config.n_channels,
        "error": config.n_channels,
        "hidden+error": config.hidden + config.n_channels,
    }[mode]


def stage1_features(
    mode: FeatureMode, hidden: torch.Tensor, estimate: torch.Tensor, error: torch.Tensor
) -> torch.Tensor:
    """What stage 2 sees at each timestep, all causal at ``t``.

    Args:
        mode: Which of stage 1's outputs to use.
        hidden: ``(B, T, H)`` hidden state after ``x_t``.
        estimate: ``(B, T, C)`` estimate of ``x_{t+1}``.
        error: ``(B, T, C)`` ``x_t − x̂_t`` (zero at a sequence's first step, which has no estimate).
    """
    if mode == "hidden":
        return hidden
    if mode == "estimate":
        return estimate
    if mode == "error":
        return error
    return torch.cat([hidden, error], dim=-1)  # (B, T, H + C)


def one_step_errors(x: torch.Tensor, estimate: torch.Tensor, previous: torch.Tensor | None = None) -> torch.Tensor:
    """``x_t − x̂_t`` for every ``t`` of a chunk: ``estimate`` is shifted by one, ``previous`` bridges chunks.

    Args:
        x: ``(B, T, C)`` normalised samples.
        estimate: ``(B, T, C)`` estimates of the next samples.
        previous: ``(B, C)`` the estimate of ``x[:, 0]`` from the chunk before, or None at a sequence's start.
    """
    shifted = torch.roll(estimate, 1, dims=1)  # shifted[:, t] = estimate[:, t - 1]
    shifted[:, 0] = x[:, 0] if previous is None else previous
    return x - shifted  # (B, T, C)


class Classifier(nn.Module):
    """Stage 2: dropout, LSTM, dropout, linear, softmax (softmax applied by the loss / at inference)."""

    def __init__(self, config: ClassifierConfig) -> None:
        super().__init__()
        self.config = config
        self.drop_in = nn.Dropout(config.dropout)  # the 20 % dropout after stage 1's LSTM layer
        self.lstm = nn.LSTM(config.n_features, config.hidden, batch_first=True)
        self.drop_out = nn.Dropout(config.dropout)  # and after this one
        self.head = nn.Linear(config.hidden, config.n_classes)

    def forward(self, features: torch.Tensor, state: State | None = None) -> tuple[torch.Tensor, State]:
        """``features (B, T, F)`` -> ``logits (B, T, K)`` and the final state."""
        out, state = self.lstm(self.drop_in(features), state)  # (B, T, H)
        return self.head(self.drop_out(out)), state
