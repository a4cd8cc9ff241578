"""Stage 1 training: the predictor learns each next sample from the past on all logs, without labels."""

from __future__ import annotations

import copy
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from .config import PredictorConfig, TrainConfig
from .data import Normalizer, Piece, cut_pieces, stage1_batch
from .losses import masked_mse, predictor_loss
from .models import Predictor
from .progress import CancelFn, Cancelled, Progress, ProgressFn, never


@dataclass
class PredictorFit:
    """A trained predictor, its input normalisation, and how training went."""

    model: Predictor
    normalizer: Normalizer
    history: list[dict[str, float]]  # per epoch: train_loss, val_loss
    best_epoch: int
    timesteps: int  # training timesteps per epoch


def split_pieces(pieces: list[Piece], val_fraction: float, rng: np.random.Generator) -> tuple[list, list]:
    """Hold out a share of pieces for early stopping (at least one, when there are two or more)."""
    order = rng.permutation(len(pieces))
    n_val = round(len(pieces) * val_fraction)
    n_val = min(max(n_val, 1), len(pieces) - 1) if len(pieces) >= 2 else 0
    val = [pieces[i] for i in order[:n_val]]
    train = [pieces[i] for i in order[n_val:]]
    return train, val or train


def _run_batch(
    model: Predictor,
    x: torch.Tensor,
    y: torch.Tensor,
    mask: torch.Tensor,
    chunk: int,
    *,
    optimizer: torch.optim.Optimizer | None,
    config: TrainConfig,
) -> tuple[float, int]:
    """One group of pieces through all its chunks, state carried between chunks. Returns (sum of MSE, count)."""
    state = None
    total, count = 0.0, 0
    for c0 in range(0, x.shape[1], chunk):
        m = mask[:, c0 : c0 + chunk]  # (B, L)
        n = int(m.sum())
        if n == 0:
            break
        estimate, _, state = model(x[:, c0 : c0 + chunk], state)  # (B, L, C)
        target = y[:, c0 : c0 + chunk]
        if optimizer is not None:
            loss = predictor_loss(estimate, target, m, model.lstm, config.elastic)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), config.clip)
            optimizer.step()
            state = (state[0].detach(), state[1].detach())  # truncated BPTT: keep the state, cut the graph
        total += float(masked_mse(estimate.detach(), target, m)) * n
        count += n
    return total, count


def fit_predictor(
    arrays: Sequence[np.ndarray],
    *,
    config: TrainConfig | None = None,
    hidden: int = 200,
    init: PredictorFit | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> PredictorFit:
    """Train stage 1 on raw (unnormalised) logs.

    Args:
        arrays: One ``(T, C)`` array per log, same channels in the same order.
        config: Training settings (the paper's by default).
        hidden: LSTM width.
        init: A previous fit to continue from (its normaliser is kept).
        progress: Called after every optimiser step.
        cancel: Polled after every step; training stops with :class:`Cancelled` when it returns True.

    Returns:
        The model at its best validation epoch.
    """
    if not arrays:
        raise ValueError("no logs to train the predictor on")
    config = config or TrainConfig()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    normalizer = init.normalizer if init else Normalizer.fit(arrays)
    data = [normalizer(a) for a in arrays]
    model = copy.deepcopy(init.model) if init else Predictor(PredictorConfig(arrays[0].shape[1], hidden))
    model.to(config.device)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    train, val = split_pieces(cut_pieces([len(a) for a in data], config.piece), config.val_fraction, rng)
    length = max(p.length for p in train + val)
    length = -(-length // config.chunk) * config.chunk  # whole chunks
    dev = config.device

    def tensors(pieces: list[Piece]) -> tuple[torch.Tensor, ...]:
        return tuple(torch.from_numpy(a).to(dev) for a in stage1_batch(data, pieces, length))

    val_batches = [tensors(val[i : i + config.batch_size]) for i in range(0, len(val), config.batch_size)]
    n_batches = -(-len(train) // config.batch_size)
    chunks_per_batch = length // config.chunk
    steps = n_batches * chunks_per_batch
    history: list[dict[str, float]] = []
    best, best_state, best_epoch, since = float("inf"), copy.deepcopy(model.state_dict()), 0, 0
    t0 = time.monotonic()

    def report(epoch: int, step: int, train_loss: float) -> None:
        val = history[-1]["val_loss"] if history else None
        best_val = None if best == float("inf") else best
        progress(Progress("predictor", 0, 1, epoch, config.max_epochs, step, steps, train_loss, val, best_val,
                          time.monotonic() - t0))  # fmt: skip

    for epoch in range(1, config.max_epochs + 1):
        model.train()
        order = rng.permutation(len(train))
        total, count, step = 0.0, 0, 0
        for b in range(n_batches):
            group = [train[i] for i in order[b * config.batch_size : (b + 1) * config.batch_size]]
            x, y, mask = tensors(group)
            s, n = _run_batch(model, x, y, mask, config.chunk, optimizer=optimizer, config=config)
            total, count, step = total + s, count + n, step + chunks_per_batch
            if cancel():
                raise Cancelled("predictor training cancelled")
            if progress:
                report(epoch, step, total / max(count, 1))
        model.eval()
        with torch.inference_mode():
            # no backward pass: one call over the whole length carries the state as the chunks would, faster
            vs = [_run_batch(model, *batch, length, optimizer=None, config=config) for batch in val_batches]
        val_loss = sum(s for s, _ in vs) / max(sum(n for _, n in vs), 1)
        history.append({"epoch": epoch, "train_loss": total / max(count, 1), "val_loss": val_loss})
        if val_loss < best - 1e-6:
            best, best_state, best_epoch, since = val_loss, copy.deepcopy(model.state_dict()), epoch, 0
        else:
            since += 1
        if progress:
            report(epoch, steps, history[-1]["train_loss"])
        if since >= config.patience:
            break
    model.load_state_dict(best_state)
    model.eval()
    return PredictorFit(model.cpu(), normalizer, history, best_epoch, sum(p.length for p in train))
