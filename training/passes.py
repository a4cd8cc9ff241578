"""The offline pass of stage 2 over whole logs: every ensemble member of any family, chunk by chunk.

Stage 1's pass is its family's (the paper family's LSTM predictor: ``paper_lstm.stage1_pass``); this one runs
any stage-2 module that maps ``(B, L, F)`` features and a state to ``(B, L, K)`` logits and the next state.

Logs of different lengths are batched together and run in chunks of time with the LSTM state carried, so the
result equals one pass over each whole log while memory holds one chunk of each log in the batch, not the logs:
the outputs are written chunk by chunk into arrays the caller gives, which may be memory-mapped files.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import torch

from .normalizer import Rows

if TYPE_CHECKING:
    from torch import nn

STEPS_PER_CALL = 1 << 17  # batch × chunk of one LSTM call: bounds its activations whatever the batch
FEATURE_FLOATS_PER_CALL = 1 << 25  # batch × chunk × width of one call's features: 128 MB


def padded_groups(lengths: Sequence[int], batch: int) -> list[list[int]]:
    """Indices of sequences of ``lengths`` in groups of at most ``batch``, longest first, as the passes batch them."""
    order = np.argsort(lengths)[::-1]  # similar lengths together: less padding
    return [order[i : i + batch].tolist() for i in range(0, len(order), batch)]


def chunk_for(batch: int, chunk: int, width: int = 0) -> int:
    """Steps per call for ``batch`` logs: bounds the LSTM's activations, and the features' block when a step's
    input is wide (the default family's stacked frames are thousands of floats per step)."""
    steps = min(chunk, max(256, STEPS_PER_CALL // max(batch, 1)))
    if width:
        steps = min(steps, max(16, FEATURE_FLOATS_PER_CALL // (max(batch, 1) * width)))
    return steps


ChunkSink = Callable[[int, int, int, np.ndarray], None]


@torch.inference_mode()
def ensemble_pass(
    models: Sequence[nn.Module],
    features: Sequence[Rows],
    sink: ChunkSink,
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> None:
    """Every ensemble member over whole logs' features, handing each chunk's probabilities to ``sink``.

    Args:
        models: The ``M`` members. Where their class has ``ensemble_forward(models)`` and it gives a function
            (``(B, L, F)`` -> ``(M, B, L, K)`` logits: stateless members sharing work, as one MiniRocket fit's folds
            share its transform), that runs once per chunk instead of each member.
        features: Per log, ``(T, F)`` features (or a ``LazyFeatures``: only one chunk is computed at a time).
        sink: Called as ``sink(log, start, stop, probs)`` with ``probs`` ``(M, stop − start, K)`` float32, in
            order of ``start`` within each log.
        chunk: Steps per LSTM call.
        batch: Logs per call.
        device: Torch device.
    """
    for model in models:
        model.to(device).eval()
    joint = getattr(type(models[0]), "ensemble_forward", None)  # members that share work run it once for all
    together = joint(models) if joint is not None else None
    # members whose step reads its own row alone (``per_row``: their ``logits (N, D) -> (N, K)``): the rows that
    # repeat the one before are found once per chunk for all of them, not once per member (at 10 h, five members'
    # search was a third of a rescoring), and each member's logits are asked of those rows only
    per_row = together is None and getattr(type(models[0]), "per_row", False)
    for group in padded_groups([len(f) for f in features], batch):
        lengths = [len(features[i]) for i in group]
        n, width = max(lengths), features[group[0]].shape[1]
        step = chunk_for(len(group), chunk, width)
        states: list = [None] * len(models)
        for c0 in range(0, n, step):
            size = min(step, n - c0)
            f = np.zeros((len(group), size, width), np.float32)  # (B, L, F)
            for j, i in enumerate(group):
                if c0 < lengths[j]:
                    f[j, : min(size, lengths[j] - c0)] = features[i][c0 : c0 + size]
            ft = torch.from_numpy(f).to(device)
            probs = np.empty((len(models), len(group), size, models[0].config.n_classes), np.float32)
            if together is not None:  # stateless members: every one's logits in one call
                probs[:] = torch.softmax(together(ft), -1).cpu().numpy()  # (M, B, L, K)
            elif per_row:
                distinct, which = distinct_rows(ft)  # (U, F), (B·L,)
                for m, model in enumerate(models):
                    logits = model.logits(distinct)[which].reshape(len(group), size, -1)  # (B, L, K)
                    probs[m] = torch.softmax(logits, -1).cpu().numpy()
            else:
                for m, model in enumerate(models):
                    logits, states[m] = model(ft, states[m])  # (B, L, K)
                    probs[m] = torch.softmax(logits, -1).cpu().numpy()
            for j, i in enumerate(group):
                k = min(size, lengths[j] - c0)
                if k > 0:
                    sink(i, c0, c0 + k, probs[:, j, :k])
                    _release(features[i])


def _release(rows: Rows) -> None:
    """Give back what reading ``rows`` put in the resident set, where they can (memory-mapped frames: a pass over a
    fleet's logs left them all resident, 1.8 GiB at 100 hours); nothing for an array or rows read on demand."""
    release = getattr(rows, "release", None)
    if release is not None:
        release()


def run_classifiers(
    models: Sequence[nn.Module],
    features: Sequence[Rows],
    *,
    chunk: int = 4096,
    batch: int = 64,
    device: str = "cpu",
) -> list[np.ndarray]:
    """Every ensemble member over whole logs' features.

    Returns:
        Per log, ``(M, T, K)`` float32 class probabilities of the ``M`` members.
    """
    k = models[0].config.n_classes
    out = [np.empty((len(models), len(f), k), np.float32) for f in features]

    def keep(i: int, a: int, b: int, probs: np.ndarray) -> None:
        out[i][:, a:b] = probs

    ensemble_pass(models, features, keep, chunk=chunk, batch=batch, device=device)
    return out


def distinct_rows(features: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``features (B, T, D)`` -> the first row of each run of identical consecutive rows, ``(U, D)``, and for each
    of the ``B·T`` rows the index of its run, ``(B·T,)``. No two consecutive distinct rows are equal, so a pass over
    them finds nothing more to merge."""
    b, t, d = features.shape
    flat = features.reshape(b * t, d)  # (B·T, D)
    new = torch.ones(b * t, dtype=torch.bool, device=flat.device)
    new[1:] = (flat[1:] != flat[:-1]).any(dim=1)
    which = torch.cumsum(new.long(), 0) - 1  # (B·T,) index of each row's distinct run
    return flat[new], which


def per_distinct_row(logits: Callable[[torch.Tensor], torch.Tensor], features: torch.Tensor) -> torch.Tensor:
    """``logits`` of ``features (B, T, D)`` computed once per run of identical consecutive rows and repeated:
    ``(B, T, K)``. A window family's input changes once per hop (a frame, a window of samples), so at 100 Hz most
    steps repeat the one before, and the network runs twenty times less."""
    b, t, _ = features.shape
    distinct, which = distinct_rows(features)  # (U, D), (B·T,)
    return logits(distinct)[which].reshape(b, t, -1)
