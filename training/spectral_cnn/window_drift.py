"""How unlike the labelled data a step's input is: the drift score of the default family.

Each ensemble member keeps two views of a sample of the labelled frames it trained on: their embeddings (the pooled
features its head reads, scaled to unit length) and their inputs (the window's standardised frames, averaged). A
step's distance in a view is the mean Euclidean distance to its ``neighbours`` nearest reference rows (deep nearest
neighbours, Sun et al. 2022). The embedding's distance is divided by its ``quantile`` over the labelled frames the
member did *not* train on (its held-out blocks), the inputs' by ``INPUT_MARGIN`` times theirs; the larger is taken
and scaled once more so that exactly ``1 − quantile`` of the held-out labelled time scores above 1. The score is the
members' mean. Pseudo-labels never enter the reference: the score says "unlike anything a person labelled".

Why this shape. The embedding tells the model's errors best: on BorealTC's *inner* folds by run (each outer fold's
held-out-run fits, their held-out labelled frames; outer test folds unread), the AUROC of drift for telling a wrong
prediction was 0.79 for unit embeddings, 0.75 raw, 0.66 for the inputs alone, 0.68 for the larger of embedding and
inputs at equal weight, and 0.79 with the inputs counted from twice their quantile. But the embedding alone misses a
robot far off: its features fall where the network's GELUs are flat, near labelled ones. On the demo walks (two
one-minute walks, 15 % labelled; share of a new walk's time above 1, raw embedding alone): a new walk of the same robot
0.45, IMU gains x3 0.73, twice the speed 0.91, all changes at once 0.17. The inputs' view sees that walk
(``tests/workbench/cycle/test_drift_session.py``), and a vibration of an unseen frequency at four times the
amplitude, which unit embeddings scored 0.9 (``tests/training/test_window_drift.py``).

Each member keeps ``WindowFitConfig.reference_rows`` of its labelled frames (1,024): the search is linear in them
(half a rescoring's time at 2,048); on inner folds the AUROC was 0.832 at 2,048, 0.831 at 1,024, 0.824 at 512.

Nothing here reads sessions or files; the bundle stores a :class:`DriftReference` beside the weights.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from ..figures import accuracy_by_drift
from .drift_reference import DRIFT_NEIGHBOURS, DRIFT_QUANTILE, INPUT_MARGIN, QUERY_CHUNK, DriftReference, scaled_drift
from .spectra import SpectralSteps, stacked_frames
from .window_classifier import WindowClassifier
from .window_config import WindowFitConfig


@torch.inference_mode()
def member_views(model: WindowClassifier, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit-length embeddings ``(N, E)`` and window-mean standardised inputs ``(N, F)`` of stacked-frame rows
    ``(N, W·F)``."""
    cfg = model.config
    emb, inp = [], []
    for c in range(0, len(rows), QUERY_CHUNK):
        x = torch.from_numpy(np.ascontiguousarray(rows[c : c + QUERY_CHUNK], np.float32))  # (n, W·F)
        frames = model.standardise(x)  # (n, W, F)
        e, i = views_of(model.pooled(frames), frames)
        emb.append(e)
        inp.append(i)
    if not emb:
        return np.zeros((0, 2 * cfg.hidden), np.float32), np.zeros((0, cfg.frame_width), np.float32)
    return np.concatenate(emb), np.concatenate(inp)


def neighbour_distance(
    reference: np.ndarray, queries: np.ndarray, neighbours: int, *, skip_self: bool = False
) -> np.ndarray:
    """Mean Euclidean distance of each query ``(N, E)`` to its ``neighbours`` nearest rows of ``reference``
    ``(R, E)``; ``skip_self`` drops each query's nearest (the query is in the reference).

    In torch: its ``topk`` picks the nearest of a 2048 × 2048 block 5 times faster than NumPy's ``partition``
    (which was a third of scoring a session), and its matrix product uses every thread it was given."""
    k = min(neighbours + int(skip_self), len(reference))
    ref = torch.from_numpy(np.ascontiguousarray(reference, np.float32))  # (R, E)
    ref_sq = ref.square().sum(dim=1)  # (R,)
    out = np.empty(len(queries), np.float32)
    for c in range(0, len(queries), QUERY_CHUNK):
        q = torch.from_numpy(np.ascontiguousarray(queries[c : c + QUERY_CHUNK], np.float32))  # (n, E)
        sq = torch.addmm(q.square().sum(dim=1)[:, None] + ref_sq[None], q, ref.T, alpha=-2.0)  # (n, R) no (n, R, E)
        near = torch.topk(sq, k, dim=1, largest=False, sorted=skip_self).values  # (n, k) the nearest, ascending
        near = near.clamp_min_(0.0).sqrt_()
        if skip_self and k > 1:
            near = near[:, 1:]
        out[c : c + QUERY_CHUNK] = near.mean(dim=1).numpy()
    return out


def _distances(
    ref: tuple[np.ndarray, np.ndarray], views: tuple[np.ndarray, np.ndarray], neighbours: int, *, skip_self: bool
) -> np.ndarray:
    """``(N, 2)`` neighbour distance of each row in each view."""
    return np.stack(
        [neighbour_distance(r, v, neighbours, skip_self=skip_self) for r, v in zip(ref, views, strict=True)], axis=1
    )


def fit_drift(
    models: Sequence[WindowClassifier],
    trained: Sequence[np.ndarray],
    held: Sequence[np.ndarray],
    *,
    seed: int = 0,
    rows_kept: int = WindowFitConfig.reference_rows,
    neighbours: int = DRIFT_NEIGHBOURS,
    quantile: float = DRIFT_QUANTILE,
) -> DriftReference:
    """The reference of an ensemble from the labelled rows each member trained on and those it did not.

    Args:
        models: The ``M`` members.
        trained: Per member, ``(N, W·F)`` labelled rows it trained on (a sample of ``rows_kept`` is kept).
        held: Per member, labelled rows it never trained on (its held-out blocks); empty for a single model, whose
            scales then come from its reference with each row's own match left out.
        seed: Seed of the sample.
        rows_kept: Most rows of a member's reference (``WindowFitConfig.reference_rows``).
        neighbours: Nearest reference rows averaged.
        quantile: The held-out quantile that scores 1.
    """
    rng = np.random.default_rng(seed)
    every = [r for r in (*trained, *held) if len(r)]
    if not every:
        raise ValueError("no labelled rows to draw the drift reference from")
    refs, inputs, scales = [], [], []
    for model, rows, out in zip(models, trained, held, strict=True):
        if len(rows) == 0:  # a member that trained on no labelled row of its own: every labelled row stands in
            rows, out = np.concatenate(every), rows
        if len(rows) > rows_kept:
            rows = rows[np.sort(rng.choice(len(rows), rows_kept, replace=False))]
        ref = member_views(model, rows)
        if len(out):
            dist = _distances(ref, member_views(model, out), neighbours, skip_self=False)  # (N, 2)
        else:
            dist = _distances(ref, ref, neighbours, skip_self=True)
        scale = np.maximum(np.quantile(dist, quantile, axis=0), 1e-6) * np.asarray([1.0, INPUT_MARGIN])  # (2,)
        scale = scale * max(float(np.quantile((dist / scale).max(axis=1), quantile)), 1e-6)  # the larger, as one
        refs.append(ref[0])
        inputs.append(ref[1])
        scales.append(scale)
    return DriftReference(tuple(refs), tuple(inputs), np.asarray(scales, np.float32), neighbours, quantile)


def views_of(pooled: torch.Tensor, frames: torch.Tensor) -> tuple[np.ndarray, np.ndarray]:
    """A member's two views of its rows from what its network computed of them: the unit-length embedding of its
    pooled features ``(N, 2H)`` and the window mean of its standardised frames ``(N, W, F)``."""
    return torch.nn.functional.normalize(pooled, dim=1).cpu().numpy(), frames.mean(dim=1).cpu().numpy()


def views_drift(reference: DriftReference, m: int, views: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Drift ``(N,)`` of rows as member ``m`` alone scores them, from their two views (:func:`views_of`)."""
    return scaled_drift(reference, m, views, distance=neighbour_distance)


def member_drift(reference: DriftReference, m: int, model: WindowClassifier, rows: np.ndarray) -> np.ndarray:
    """Drift ``(N,)`` of stacked-frame rows ``(N, W·F)`` as member ``m`` alone scores them."""
    return views_drift(reference, m, member_views(model, rows))


def drift_of_rows(reference: DriftReference, models: Sequence[WindowClassifier], rows: np.ndarray) -> np.ndarray:
    """Drift ``(N,)`` of stacked-frame rows ``(N, W·F)``: the members' mean of the larger scaled view distance."""
    total = np.zeros(len(rows), np.float32)
    for m, model in enumerate(models):
        total += member_drift(reference, m, model, rows)
    return total / len(models)


def held_out_relation(
    reference: DriftReference,
    models: Sequence[WindowClassifier],
    held: Sequence[np.ndarray],
    right: Sequence[np.ndarray],
) -> dict | None:
    """The relation between drift and accuracy (:func:`training.figures.drift_accuracy.accuracy_by_drift`) on each
    member's held-out rows ``held[m] (N_m, W·F)``, whether member ``m`` predicted each right ``right[m] (N_m,)``,
    each row's drift scored by that member alone: the one that never trained on it."""
    drift = [member_drift(reference, m, model, rows) for m, (model, rows) in enumerate(zip(models, held, strict=True))]
    if not any(len(d) for d in drift):
        return None
    return accuracy_by_drift(np.concatenate(drift), np.concatenate([np.asarray(r, bool) for r in right]))


def drift_of_log(reference: DriftReference, models: Sequence[WindowClassifier], features: SpectralSteps) -> np.ndarray:
    """Drift ``(T,)`` of every step of one log: its last completed frame's (the first frame's before it completes).

    The frames are stacked a chunk at a time: an hour's stacked rows at once would be 110 MB.
    """
    cfg = features.config
    frames = np.asarray(features.frames, np.float32)  # (N, F)
    n, t = len(frames), len(features)
    if n == 0:
        return np.zeros(t, np.float32)
    per_frame = np.empty(n, np.float32)
    for c in range(0, n, QUERY_CHUNK):
        idx = np.arange(c, min(c + QUERY_CHUNK, n))
        per_frame[idx] = drift_of_rows(reference, models, stacked_frames(frames, idx, cfg.window))
    steps = np.arange(t)
    which = np.clip((steps - (cfg.frame - 1)) // cfg.hop, 0, n - 1)  # (T,) the last completed frame
    return per_frame[which]
