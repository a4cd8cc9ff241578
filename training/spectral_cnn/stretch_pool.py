"""Self-training's pool: the frame rows of the unlabelled stretches, every ``PSEUDO_STRIDE``-th of them, in one
array, drawn to a memory budget on a fleet's hours; and the rows a labelled segment contributes."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .spectra import SpectralSteps

PSEUDO_STRIDE = 3  # rows of a stretch self-training reads: every third frame
Stretch = tuple[int, int, int]  # (log index, start, stop): unlabelled, no change point inside


def frame_rows(features: SpectralSteps, start: int, stop: int, *, stride: int = 1) -> np.ndarray:
    """The distinct inputs of steps ``[start, stop)``: one per completed frame (the last step when none); with
    ``stride``, every ``stride``-th of them."""
    return features.at(_row_steps(features, start, stop, stride))


def _row_steps(features: SpectralSteps, start: int, stop: int, stride: int) -> np.ndarray:
    steps = features.frame_rows(start, stop)
    if len(steps) == 0 and stop - 1 >= features.config.frame - 1:
        steps = np.asarray([stop - 1])
    return steps[::stride]


def pool_draw(
    features: Sequence[SpectralSteps],
    stretches: Sequence[Stretch],
    *,
    budget_mib: float,
    seed: int,
    share: float = 1.0,
) -> np.ndarray:
    """Which ``stretches`` self-training's pool holds ``(S,)``: all of them, or as many, drawn at random (``seed``),
    as fit ``budget_mib`` (0: no bound) and ``share`` of their bytes (their rows as :func:`stretch_pool` fills them).
    A stretch is kept whole or left out, so the rule that its rows agree judges what it did before; only fewer of
    them are judged."""
    keep = np.ones(len(stretches), bool)
    if not stretches or (budget_mib <= 0 and share >= 1.0):
        return keep
    row_bytes = 4 * features[0].shape[1]
    sizes = np.asarray([len(_row_steps(features[i], a, b, PSEUDO_STRIDE)) for i, a, b in stretches]) * row_bytes
    budget = share * sizes.sum()
    if budget_mib > 0:
        budget = min(budget, budget_mib * 2**20)
    if sizes.sum() <= budget:
        return keep
    order = np.random.default_rng(seed).permutation(len(stretches))
    keep[:] = False
    keep[order[np.cumsum(sizes[order]) <= budget]] = True
    return keep


def every_row(features: SpectralSteps, start: int, stop: int) -> np.ndarray:
    """The steps of ``[start, stop)`` whose rows a labelled segment contributes (:func:`frame_rows`'s)."""
    return _row_steps(features, start, stop, 1)


def stretch_pool(
    features: Sequence[SpectralSteps], stretches: Sequence[Stretch], stride: int, *, keep: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Every ``stride``-th frame row of each stretch in one array ``(N, W·F)``, and where each stretch's rows begin
    and end in it ``(S + 1,)``; a stretch ``keep`` leaves out has none. One array filled in place: per-stretch arrays
    (or strided views of all rows) held three times the memory on 10 hours of logs."""
    counts = [
        len(_row_steps(features[i], a, b, stride)) if keep is None or keep[j] else 0
        for j, (i, a, b) in enumerate(stretches)
    ]
    bounds = np.concatenate([[0], np.cumsum(counts, dtype=np.int64)])
    pool = np.empty((int(bounds[-1]), features[0].shape[1] if features else 0), np.float32)
    for j, (i, a, b) in enumerate(stretches):
        if counts[j]:
            pool[bounds[j] : bounds[j + 1]] = frame_rows(features[i], a, b, stride=stride)
            features[i].release()  # the pool holds its copy: at 100 h every log's mapped frames stayed resident
    return pool, bounds
