"""A terrain's weight in the window network's loss when it has less labelled time than the others (logit adjustment:
Menon et al. 2021).

Three ways are offered (:attr:`.window_config.WindowFitConfig.balance`), each a function of the terrains' shares
of the training rows, ``prior``:

- ``weights``: each row's cross-entropy weighted by ``1 / (K' · prior)`` (``K'`` the terrains present), so every
  terrain present adds the same total weight and a row's mean weight stays one;
- ``sampling``: each epoch draws its rows with replacement, a row's chance ``1 / (K' · count of its terrain)``;
- ``logits``: logit adjustment (Menon et al., 2021): the loss reads ``logits + log(prior)``; prediction reads the
  logits alone, which then rank terrains as if every one had the same share. A terrain absent from the rows gets no
  offset, so it stays as unlikely as plain cross-entropy leaves it.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.nn import functional as F

from .window_config import Balance


def class_shares(y: np.ndarray, k: int) -> np.ndarray:
    """Each of the ``k`` classes' share of the rows ``y (N,)``, ``(k,)`` float64 (zeros when there are none)."""
    counts = np.bincount(np.asarray(y, np.int64), minlength=k)[:k].astype(np.float64)
    return counts / max(counts.sum(), 1.0)


class BalancedLoss:
    """Cross-entropy with the fit's ``balance`` applied, for rows whose classes have shares ``prior (K,)``.

    Args:
        balance: The fit's setting.
        prior: Each class's share of the training rows (:func:`class_shares`).
        device: Where the logits it is called with are.
    """

    def __init__(self, balance: Balance, prior: np.ndarray, *, device: torch.device | str = "cpu") -> None:
        self.balance = balance
        present = prior > 0
        self.weight = None
        self.offset = None
        if balance == "weights":
            w = np.where(present, 1.0 / (present.sum() * np.where(present, prior, 1.0)), 0.0)
            self.weight = torch.as_tensor(w, dtype=torch.float32, device=device)  # (K,)
        elif balance == "logits":
            log_prior = np.where(present, np.log(np.where(present, prior, 1.0)), 0.0)
            self.offset = torch.as_tensor(log_prior, dtype=torch.float32, device=device)  # (K,)
        elif balance not in ("none", "sampling"):
            raise ValueError(f"unknown balance {balance!r}: none, weights, sampling or logits")

    def __call__(self, logits: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """The mean loss of a batch: ``logits (B, K)``, classes ``y (B,)``."""
        if self.offset is not None:
            logits = logits + self.offset
        return F.cross_entropy(logits, y, weight=self.weight)


def epoch_order(y: torch.Tensor, balance: Balance, generator: torch.Generator) -> torch.Tensor:
    """The row indices of one epoch over rows of classes ``y (N,)``: a permutation, or with ``"sampling"``, ``N``
    draws with replacement that give every class present the same chance."""
    if balance != "sampling":
        return torch.randperm(len(y), generator=generator)
    counts = torch.bincount(y)
    chance = 1.0 / counts[y].double()  # (N,) each class's rows share one unit
    return torch.multinomial(chance, len(y), replacement=True, generator=generator)
