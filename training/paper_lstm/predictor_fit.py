"""Stage 1 training: the predictor learns each next sample from the past on all logs, without labels.

The same loop runs in one process or in several under ``torchrun`` (``training.distributed``): each global batch
of ``batch_size`` pieces is split among the processes, ``DistributedDataParallel`` averages their gradients, and the
loss is scaled so that the average equals the one-process loss of the whole batch. Logs are read a batch at a time
(the next batch is read while this one trains), so memory does not grow with the number or length of logs.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch.nn.parallel import DistributedDataParallel

from .. import distributed
from ..fitting import to_dict
from ..normalizer import Normalizer, Rows
from ..running import (
    CancelFn,
    Cancelled,
    Checkpoint,
    Progress,
    ProgressFn,
    fingerprint,
    keyed_path,
    load_checkpoint,
    never,
    other_checkpoints,
    save_checkpoint,
)
from .lstm_config import PredictorConfig, TrainConfig
from .lstm_losses import masked_mse, predictor_loss
from .lstm_models import Predictor
from .pieces import Piece, cut_pieces, stage1_batch


@dataclass
class PredictorFit:
    """A trained predictor, its input normalisation, and how training went."""

    model: Predictor
    normalizer: Normalizer
    history: list[dict[str, float]]  # per epoch: train_loss, val_loss
    best_epoch: int
    timesteps: int  # training timesteps per epoch
    resumed_from: tuple[int, int] | None = None  # (epoch, batch) of the checkpoint it went on from
    checkpoint: Path | None = None  # the file this run kept (the caller deletes it once the result is saved)


def split_pieces(pieces: list[Piece], val_fraction: float, rng: np.random.Generator) -> tuple[list, list]:
    """Hold out a share of pieces for early stopping (at least one, when there are two or more)."""
    order = rng.permutation(len(pieces))
    n_val = round(len(pieces) * val_fraction)
    n_val = min(max(n_val, 1), len(pieces) - 1) if len(pieces) >= 2 else 0
    val = [pieces[i] for i in order[:n_val]]
    train = [pieces[i] for i in order[n_val:]]
    return train, val or train


def _run_batch(
    net: torch.nn.Module,
    model: Predictor,
    x: torch.Tensor,
    y: torch.Tensor,
    mask: torch.Tensor,
    chunk: int,
    *,
    optimizer: torch.optim.Optimizer | None,
    config: TrainConfig,
    world: distributed.World,
    autocast: bool = False,
) -> tuple[float, int]:
    """One group of pieces through all its chunks, state carried between chunks. Returns (sum of MSE, count).

    ``net`` is ``model`` or its ``DistributedDataParallel`` wrapper. With several processes each holds part of the
    group; the data term is scaled by ``n_here * world / n_all`` so that DDP's average of the gradients is the
    gradient of the mean over the whole group, as one process would compute it.
    """
    state = None
    total, count = 0.0, 0
    for c0 in range(0, x.shape[1], chunk):
        m = mask[:, c0 : c0 + chunk]  # (B, L)
        n = int(m.sum())
        n_all = int(distributed.all_sum([n])[0]) if world.distributed and optimizer is not None else n
        if n_all == 0:
            break
        with torch.autocast(x.device.type, dtype=torch.bfloat16, enabled=autocast):
            estimate, _, state = net(x[:, c0 : c0 + chunk], state)  # (B, L, C)
        estimate = estimate.float()
        target = y[:, c0 : c0 + chunk]
        if optimizer is not None:
            scale = n * world.size / n_all if world.distributed else 1.0
            loss = predictor_loss(estimate, target, m, model.lstm, config.elastic, data_scale=scale)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), config.clip)
            optimizer.step()
            state = (state[0].detach(), state[1].detach())  # truncated BPTT: keep the state, cut the graph
        total += float(masked_mse(estimate.detach(), target, m)) * n
        count += n
    return total, count


class _Prefetch:
    """Reads the next batch while the current one trains: at most two batches are in memory."""

    def __init__(self, make: Callable[[int], tuple[torch.Tensor, ...]], n: int, first: int = 0) -> None:
        self._make, self._n = make, n
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="stage1-read")
        self._next = self._pool.submit(make, first) if first < n else None

    def get(self, b: int) -> tuple[torch.Tensor, ...]:
        assert self._next is not None
        batch = self._next.result()
        self._next = self._pool.submit(self._make, b + 1) if b + 1 < self._n else None
        return batch

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def _device(config: TrainConfig, world: distributed.World) -> torch.device:
    if config.device.startswith("cuda") and world.distributed:
        return torch.device("cuda", world.local_rank)
    return torch.device(config.device)


def fit_predictor(
    arrays: Sequence[Rows],
    *,
    config: TrainConfig | None = None,
    hidden: int = 200,
    init: PredictorFit | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    checkpoint: str | Path | None = None,
    checkpoint_every: int = 100,
    on_resume: Callable[[int, int], None] | None = None,
    on_other: Callable[[str], None] | None = None,
) -> PredictorFit:
    """Train stage 1 on raw (unnormalised) logs, in this process or in all of a ``torchrun`` group.

    Args:
        arrays: One ``(T, C)`` log each, same channels in the same order: arrays, memory maps or rows read on
            demand (only each batch's rows are read).
        config: Training settings (the paper's by default).
        hidden: LSTM width.
        init: A previous fit to continue from (its normaliser is kept).
        progress: Called after every optimiser step (in the main process only).
        cancel: Polled after every step; training stops with :class:`Cancelled` when it returns True.
        checkpoint: Where checkpoints live: the run keeps ``keyed_path(checkpoint, fingerprint)`` up to date
            (written by the main process only) and resumes from it; a run of other settings or data has its own
            file, so neither replaces the other.
        checkpoint_every: Batches between checkpoints (and one at the end of every epoch).
        on_resume: Called with (epoch, batch) when training goes on from the checkpoint.
        on_other: Called with one line per checkpoint of another run found beside it (its epoch, how it differs),
            when this run starts afresh: nobody loses a run to a changed flag without being told.

    Returns:
        The model at its best validation epoch.
    """
    if not arrays:
        raise ValueError("no logs to train the predictor on")
    config = config or TrainConfig()
    world = distributed.current()
    dev = _device(config, world)
    autocast = dev.type == "cuda" and config.bf16
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    normalizer = init.normalizer if init else Normalizer.fit(arrays)
    model = copy.deepcopy(init.model) if init else Predictor(PredictorConfig(arrays[0].shape[1], hidden))
    model.to(dev)
    optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
    train, val = split_pieces(cut_pieces([len(a) for a in arrays], config.piece), config.val_fraction, rng)
    length = max(p.length for p in train + val)
    length = -(-length // config.chunk) * config.chunk  # whole chunks
    n_batches = -(-len(train) // config.batch_size)
    chunks_per_batch = length // config.chunk
    steps = n_batches * chunks_per_batch
    net: torch.nn.Module = model
    if world.distributed:
        net = DistributedDataParallel(model, device_ids=[dev.index] if dev.type == "cuda" else None)

    def tensors_local(pieces: list[Piece]) -> tuple[torch.Tensor, ...]:
        return tuple(torch.from_numpy(a).to(dev) for a in stage1_batch(arrays, pieces, length, normalizer))

    def tensors(pieces: list[Piece]) -> tuple[torch.Tensor, ...]:
        here = pieces[world.rank :: world.size]  # this process's share of the global batch
        x, y, mask = tensors_local(here or pieces[:1])
        if not here:  # fewer pieces than processes: run one with no loss, so every process steps together
            mask = torch.zeros_like(mask)
        return x, y, mask

    # settings and data a checkpoint must share to be resumed; not the device or the number of processes
    settings = {
        "config": {k: v for k, v in to_dict(config).items() if k not in ("device", "bf16")},
        "hidden": hidden,
        "lengths": [len(a) for a in arrays],
        "channels": arrays[0].shape[1],
        "init": None if init is None else init.normalizer.to_dict(),
    }
    key = fingerprint(**settings)
    ckpt = None
    if checkpoint is not None:
        base, checkpoint = Path(checkpoint), keyed_path(checkpoint, key)
        ckpt = load_checkpoint(checkpoint, key)
        if ckpt is None and on_other is not None and world.main:
            for line in other_checkpoints(base, key, {**settings["config"], "hidden": hidden}):
                on_other(line)
    history: list[dict[str, float]] = []
    best, best_state, best_epoch, since = float("inf"), copy.deepcopy(model.state_dict()), 0, 0
    start_epoch, start_batch, done, order = 1, 0, False, None
    carried = (0.0, 0.0)  # the epoch's loss sums up to the checkpoint (all processes), counted once: in the main
    if ckpt is not None:
        model.load_state_dict(ckpt.model)
        optimizer.load_state_dict(ckpt.optimizer)
        rng.bit_generator.state = ckpt.rng
        history, best, best_epoch, since = ckpt.history, ckpt.best, ckpt.best_epoch, ckpt.since
        best_state = {k: v.to(dev) for k, v in ckpt.best_model.items()}
        start_epoch, start_batch, done = ckpt.epoch, ckpt.batch, ckpt.done
        order = ckpt.order.numpy() if ckpt.batch > 0 else None
        carried = (ckpt.total, ckpt.count) if world.main else (0.0, 0.0)
        if on_resume is not None:
            on_resume(ckpt.epoch, ckpt.batch)
    t0 = time.monotonic()

    def report(epoch: int, step: int, train_loss: float) -> None:
        if progress is None or not world.main:
            return
        val = history[-1]["val_loss"] if history else None
        best_val = None if best == float("inf") else best
        progress(
            Progress(
                "predictor",
                0,
                1,
                epoch,
                config.max_epochs,
                step,
                steps,
                train_loss,
                val,
                best_val,
                time.monotonic() - t0,
            )
        )

    def save(epoch: int, batch: int, order: np.ndarray, total: float, count: float, finished: bool) -> None:
        if checkpoint is None:
            return
        total, count = distributed.all_sum([total, count])  # every process calls this at the same batch
        if world.main:
            save_checkpoint(
                Checkpoint(
                    key,
                    epoch,
                    batch,
                    finished,
                    total,
                    count,
                    history,
                    best,
                    best_epoch,
                    since,
                    rng.bit_generator.state,
                    torch.from_numpy(np.asarray(order, np.int64)),
                    model.state_dict(),
                    best_state,
                    optimizer.state_dict(),
                    {**settings["config"], "hidden": hidden},
                ),
                checkpoint,
            )

    epoch = start_epoch
    while not done and epoch <= config.max_epochs:
        model.train()
        if order is None:
            order = rng.permutation(len(train))
        first = start_batch if epoch == start_epoch else 0
        total, count = carried if epoch == start_epoch else (0.0, 0.0)
        step = first * chunks_per_batch
        reader = _Prefetch(
            lambda b, order=order: tensors(
                [train[i] for i in order[b * config.batch_size : (b + 1) * config.batch_size]]
            ),
            n_batches,
            first,
        )
        try:
            for b in range(first, n_batches):
                x, y, mask = reader.get(b)
                s, n = _run_batch(
                    net,
                    model,
                    x,
                    y,
                    mask,
                    config.chunk,
                    optimizer=optimizer,
                    config=config,
                    world=world,
                    autocast=autocast,
                )
                total, count, step = total + s, count + n, step + chunks_per_batch
                if cancel():
                    raise Cancelled("predictor training cancelled")
                report(epoch, step, total / max(count, 1))
                if (b + 1) % checkpoint_every == 0 and b + 1 < n_batches:
                    save(epoch, b + 1, order, total, count, False)
        finally:
            reader.close()
        total, count = distributed.all_sum([total, count])
        model.eval()
        with torch.inference_mode():
            # no backward pass: one call over the whole length carries the state as the chunks would, faster
            mine = val[world.rank :: world.size]  # this process's share of the validation pieces
            v_total, v_count = 0.0, 0
            for i in range(0, len(mine), config.batch_size):
                x, y, mask = tensors_local(mine[i : i + config.batch_size])
                s, n = _run_batch(
                    model, model, x, y, mask, length, optimizer=None, config=config, world=world, autocast=autocast
                )
                v_total, v_count = v_total + s, v_count + n
        v_total, v_count = distributed.all_sum([v_total, v_count])
        val_loss = v_total / max(v_count, 1)
        history.append({"epoch": epoch, "train_loss": total / max(count, 1), "val_loss": val_loss})
        if val_loss < best - 1e-6:
            best, best_state, best_epoch, since = val_loss, copy.deepcopy(model.state_dict()), epoch, 0
        else:
            since += 1
        report(epoch, steps, history[-1]["train_loss"])
        done = since >= config.patience or epoch == config.max_epochs
        order = None
        epoch += 1
        save(epoch, 0, np.zeros(0, np.int64), 0.0, 0.0, done)

    model.load_state_dict(best_state)
    model.eval()
    resumed = None if ckpt is None else (ckpt.epoch, ckpt.batch)
    return PredictorFit(model.cpu(), normalizer, history, best_epoch, sum(p.length for p in train), resumed, checkpoint)
