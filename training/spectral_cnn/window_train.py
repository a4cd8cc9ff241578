"""One network's training on frame rows: AdamW over batches drawn class-balanced, with the row draws (noise, dropped
frames) and the augmentation seeded by the fit, so a network's weights are a function of its rows, classes, settings
and seed alone (what :mod:`.fit_starts` relies on)."""

from __future__ import annotations

import numpy as np
import torch

from ..running import CancelFn, Cancelled
from .class_balance import BalancedLoss, class_shares, epoch_order
from .row_draws import RowDraws
from .spectra import SpectralConfig
from .window_augment import augment_rows
from .window_classifier import WindowClassifier
from .window_config import WindowFitConfig
from .window_rows import WindowRows


def train_rows(
    model: WindowClassifier,
    x: np.ndarray | WindowRows,
    y: np.ndarray,
    epochs: int,
    config: WindowFitConfig,
    seed: int,
    cancel: CancelFn,
    *,
    front: SpectralConfig | None = None,
    more: tuple[np.ndarray, np.ndarray] | None = None,
    prior: np.ndarray | None = None,
) -> WindowClassifier:
    """``epochs`` passes of AdamW over rows ``x (N, W·F)`` (stacked, or :class:`WindowRows`) with classes ``y (N,)``
    (at most ``config.max_steps``); ``config.augment``'s draws need the frames' layout, ``front``. ``more``: rows
    ``pool[index]`` after ``x`` (``y`` covers both), read where they are: the batches of ``x`` and ``pool[index]``
    concatenated, without the copy.
    ``prior``: the classes' shares ``config.balance`` evens out (default: their shares of ``y``). The batches are
    gathered and drawn on the CPU and trained where ``model`` is."""
    dev = model.in_mean.device
    gen = torch.Generator().manual_seed(seed)
    draws = RowDraws(seed, dropout=model.config.dropout)
    augment = config.augment if front is not None and config.augment.active else None
    if augment is not None:  # its draws mix rows of the whole set: every row stacked
        x = x.dense() if isinstance(x, WindowRows) else x
        if more is not None:
            x, more = np.concatenate([x, more[0][more[1]]]), None
    rows = _Rows(x if isinstance(x, WindowRows) else torch.from_numpy(np.ascontiguousarray(x, np.float32)), more)
    yt = torch.from_numpy(np.asarray(y, np.int64))
    k = model.config.n_classes
    loss_of = BalancedLoss(config.balance, class_shares(y, k) if prior is None else np.asarray(prior), device=dev)
    mean = model.in_mean.cpu()  # the augmentation's draws fill dropped channels with it, on the CPU
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=config.weight_decay, fused=True)
    per_epoch = -(-len(rows) // config.batch)
    epochs = max(1, min(epochs, config.max_steps // max(per_epoch, 1)))
    model.train()
    left = config.max_steps  # an epoch longer than the budget (a huge label set) stops part-way
    for _ in range(epochs):
        if cancel():
            raise Cancelled("classifier training cancelled")
        for idx in epoch_order(yt, config.balance, gen).split(config.batch)[:left]:
            left -= 1
            xb, idx = rows.take(idx)
            if augment is not None:
                xb = augment_rows(xb, yt[idx], (rows.x, yt), front, mean, augment, gen)
            frames = model.standardise(xb.to(dev, non_blocking=True))  # (B, W, F)
            noise, keep = draws(frames.shape)  # (B, W, F) each
            frames = frames.add_(noise.to(dev, non_blocking=True), alpha=config.noise)  # in standardised units
            loss = loss_of(model.frame_logits(frames, keep=keep.to(dev, non_blocking=True)), yt[idx].to(dev))
            opt.zero_grad()
            loss.backward()
            opt.step()
        if not torch.isfinite(loss):
            raise ValueError("the window classifier's training diverged (a non-finite loss)")
    return model.eval()


class _Rows:
    """Rows ``x (N, D)`` (a tensor, or :class:`WindowRows` stacked a batch at a time) followed by ``pool[index]``,
    read as one array without building it."""

    def __init__(self, x: torch.Tensor | WindowRows, more: tuple[np.ndarray, np.ndarray] | None) -> None:
        self.x = x
        self.pool = None if more is None else torch.from_numpy(more[0])
        self.index = None if more is None else torch.from_numpy(np.asarray(more[1], np.int64))

    def __len__(self) -> int:
        return len(self.x) + (0 if self.index is None else len(self.index))

    def take(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Rows ``idx``, and ``idx`` reordered as the rows are: those of ``x`` first, then the pool's (a batch's
        order does not matter to its mean loss, and two gathers into place beat masked writes)."""
        if self.pool is None:
            return self._own(idx), idx
        n = len(self.x)
        own = idx < n
        mine, theirs = idx[own], idx[~own]
        out = torch.empty((len(idx), self.x.shape[1]), dtype=torch.float32)
        if isinstance(self.x, WindowRows):
            out[: len(mine)] = torch.from_numpy(self.x.take(mine.numpy()))
        else:
            torch.index_select(self.x, 0, mine, out=out[: len(mine)])
        torch.index_select(self.pool, 0, self.index[theirs - n], out=out[len(mine) :])
        return out, torch.cat([mine, theirs])

    def _own(self, idx: torch.Tensor) -> torch.Tensor:
        return torch.from_numpy(self.x.take(idx.numpy())) if isinstance(self.x, WindowRows) else self.x[idx]
