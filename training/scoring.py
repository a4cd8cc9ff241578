"""Per-timestep scores of a log from one pass of both stages: surprise, probabilities, uncertainty."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

_EPS = 1e-12


def entropy(probs: np.ndarray, axis: int = -1) -> np.ndarray:
    """Shannon entropy (nats) of probability vectors along ``axis``: ``(..., K)`` -> ``(...)``."""
    p = np.clip(probs, _EPS, 1.0)
    return -(p * np.log(p)).sum(axis=axis)


@dataclass(frozen=True)
class LogScores:
    """Scores of one log, one row per timestep.

    Attributes:
        error: ``(T, C)`` squared stage-1 prediction error per channel (normalised units).
        error_total: ``(T,)`` mean over channels of ``error``.
        probs: ``(T, K)`` ensemble-mean class probabilities.
        entropy: ``(T,)`` predictive entropy of ``probs`` (nats).
        disagreement: ``(T,)`` mutual information between prediction and ensemble member (BALD), nats.
    """

    error: np.ndarray
    error_total: np.ndarray
    probs: np.ndarray
    entropy: np.ndarray
    disagreement: np.ndarray

    @property
    def predicted(self) -> np.ndarray:
        """``(T,)`` most probable class index."""
        return self.probs.argmax(axis=-1)


def score_log(error: np.ndarray, member_probs: np.ndarray) -> LogScores:
    """Combine stage-1 errors and the members' probabilities of one log.

    Args:
        error: ``(T, C)`` one-step prediction errors ``x_t − x̂_t`` (normalised).
        member_probs: ``(M, T, K)`` probabilities of each of ``M`` ensemble members.
    """
    sq = np.square(error, dtype=np.float32)  # (T, C)
    mean = member_probs.mean(axis=0)  # (T, K)
    h_mean = entropy(mean)  # (T,)
    mutual = h_mean - entropy(member_probs).mean(axis=0)  # (T,) ≥ 0 up to rounding
    return LogScores(sq, sq.mean(axis=1), mean, h_mean, np.maximum(mutual, 0.0))
