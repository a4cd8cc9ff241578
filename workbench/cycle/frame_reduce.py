"""A log's scores from its ensemble's answers once per frame, each repeated over the steps that read that frame last:
what the session's pass (PyTorch, :func:`.scores.score_logs`) and ``classify``'s pass over files (NumPy, without
PyTorch) both hand on, so the two cannot differ in how a frame's answer becomes a step's."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

import labeling
from training import FrameChunk, SpectralSteps, step_frames


def frame_log_scores(
    chunks: Iterable[FrameChunk], blank: np.ndarray, features: SpectralSteps, surprise: np.ndarray, *, drift: bool
) -> labeling.LogScores:
    """One log's scores: mean probabilities, the members' mutual information and agreement, and drift per step.

    Args:
        chunks: The members' answers over every frame of the log, in order.
        blank: ``(M, K)`` the members' answers for a step before the first frame completes (it reads zeros; its drift
            is the first frame's, as ``drift_of_log`` gives).
        features: The log's stage-2 inputs (released once the chunks are read: its mapped frames not held).
        surprise: ``(T,)`` stage-1 error.
        drift: The chunks carry drift.
    """
    n, (members, k) = len(features.frames), blank.shape
    mean, mi = np.empty((n + 1, k), np.float32), np.empty(n + 1, np.float32)  # the last row: the blank input's
    agreement = np.empty(n + 1, np.float32) if members >= 2 else None  # the members' agreement needs a pair
    drifts = np.zeros(max(n, 1), np.float32) if drift else None

    def reduce(a: int, b: int, probs: np.ndarray) -> None:  # probs: (M, b - a, K)
        mean[a:b] = probs.mean(axis=0)
        mi[a:b] = labeling.mutual_information(probs)
        if agreement is not None:
            agreement[a:b] = labeling.member_agreement(probs)

    for part in chunks:
        reduce(part.start, part.start + part.probs.shape[1], part.probs)
        if drifts is not None and part.drift is not None:
            drifts[part.start : part.start + len(part.drift)] = part.drift
    reduce(n, n + 1, blank[:, None])
    features.release()
    which = step_frames(features)  # (T,)
    rows = np.where(which >= 0, which, n)  # (T,) a blank step reads the last row
    return labeling.LogScores(
        np.asarray(surprise),
        mean[rows],
        mi[rows],
        None if drifts is None else drifts[np.clip(which, 0, max(n - 1, 0))],
        None if agreement is None else agreement[rows],
    )
