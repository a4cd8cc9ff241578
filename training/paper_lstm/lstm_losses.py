"""The paper's losses: eq. (1) MSE and eq. (2) cross-entropy, each plus an elastic net on its LSTM's weights."""

from __future__ import annotations

import torch
from torch import nn

from .lstm_config import ElasticNet


def lstm_parameters(lstm: nn.LSTM) -> list[torch.Tensor]:
    """The W (input-hidden), U (hidden-hidden) and B (bias) tensors of an LSTM: what the penalty covers."""
    return [p for name, p in lstm.named_parameters() if name.startswith(("weight_ih", "weight_hh", "bias_"))]


def elastic_net(params: list[torch.Tensor], penalty: ElasticNet) -> torch.Tensor:
    """``λ(γ·Σ‖θ‖₁ + (1−γ)·Σ‖θ‖₂²)`` summed over ``params``."""
    l1 = sum(p.abs().sum() for p in params)
    l2 = sum(p.pow(2).sum() for p in params)
    return penalty.lam * (penalty.gamma * l1 + (1.0 - penalty.gamma) * l2)


def masked_mse(estimate: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean squared error over the timesteps where ``mask`` is true.

    Args:
        estimate: ``(B, T, C)``.
        target: ``(B, T, C)``.
        mask: ``(B, T)`` bool.
    """
    err = (estimate - target).pow(2).mean(dim=-1)  # (B, T)
    return (err * mask).sum() / mask.sum().clamp_min(1)


def masked_cross_entropy(
    logits: torch.Tensor, labels: torch.Tensor, mask: torch.Tensor, weight: torch.Tensor | None = None
) -> torch.Tensor:
    """``−Σ y log ŷ`` averaged over the labelled timesteps (the paper prints it without the minus sign).

    Args:
        logits: ``(B, T, K)``.
        labels: ``(B, T)`` class indices (any value where ``mask`` is false).
        mask: ``(B, T)`` bool.
        weight: ``(K,)`` per-class weights: a weighted mean, so each class counts by its weight, not its share of
            the labelled steps. ``None``: every step counts the same.
    """
    y = labels.flatten().clamp_min(0)  # (B*T,)
    ce = nn.functional.cross_entropy(logits.flatten(0, 1), y, reduction="none")  # (B*T,)
    m = mask.flatten().to(ce.dtype)
    if weight is not None:
        m = m * weight.to(ce.dtype)[y]
    return (ce * m).sum() / m.sum().clamp_min(1e-12)


def predictor_loss(
    estimate: torch.Tensor,
    target: torch.Tensor,
    mask: torch.Tensor,
    lstm: nn.LSTM,
    penalty: ElasticNet,
    *,
    data_scale: float = 1.0,
) -> torch.Tensor:
    """Eq. (1): MSE of the next-sample estimate plus the elastic net on the predictor's LSTM.

    ``data_scale`` multiplies the MSE alone: a process of a data-parallel group weighs its share of the batch so
    that the group's averaged gradient is the one-process gradient (``paper_lstm.predictor_fit``).
    """
    return masked_mse(estimate, target, mask) * data_scale + elastic_net(lstm_parameters(lstm), penalty)


def classifier_loss(
    logits: torch.Tensor,
    labels: torch.Tensor,
    mask: torch.Tensor,
    lstm: nn.LSTM,
    penalty: ElasticNet,
    weight: torch.Tensor | None = None,
) -> torch.Tensor:
    """Eq. (2): cross-entropy (class-weighted when ``weight`` is given) plus the elastic net on the classifier's
    LSTM."""
    return masked_cross_entropy(logits, labels, mask, weight) + elastic_net(lstm_parameters(lstm), penalty)


def consistency_loss(logits: torch.Tensor, last: torch.Tensor) -> torch.Tensor:
    """Mean squared distance between the class probabilities at the last step of paired sequences.

    Args:
        logits: ``(2P, T, K)``: the first sequence of every pair, then the second of every pair in the same order.
        last: ``(2P,)`` index of each sequence's last step (sequences may be padded).

    Returns:
        ``mean_p ‖softmax(a_p) − softmax(b_p)‖²``, between 0 and 2.
    """
    probs = logits[torch.arange(len(last), device=logits.device), last].float().softmax(-1)  # (2P, K)
    a, b = probs.chunk(2)  # (P, K) each
    return (a - b).pow(2).sum(-1).mean()
