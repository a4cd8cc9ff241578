"""Verification checks after the loop's last round: uniform pieces of the new runs' time nobody labelled, checked
by the reference as a person would, counted apart from the rounds' suggestions and never labelled.

They test the model the session ends with (a check tests the model that was active when it was made; the rounds'
checks tested earlier ones). ``labeling.powered_accuracy`` turns them, with the model's confidence over all that
time, into the session's accuracy with a 90 % interval; the loop's report says whether it covers the truth.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

import labeling
from sessions import LogInfo, Session

from ..cycle import SessionScores

PIECE_S = 1.0  # a verification check's length: a suggestion's


@dataclass(frozen=True)
class Verified:
    """The session's accuracy from the verification checks.

    Attributes:
        accuracy: The estimate.
        low: The 90 % interval's lower bound.
        high: Its upper bound.
        checks: How many checks it rests on.
        truth: The accuracy the reference gives the same time.
        checks_right: The checks' mean share of steps named right (the checks alone).
    """

    accuracy: float
    low: float
    high: float
    checks: int
    truth: float
    checks_right: float

    @property
    def covers(self) -> bool:
        """Whether the interval holds the truth."""
        return self.low <= self.truth <= self.high


def _allocate(sizes: Sequence[int], k: int) -> list[int]:
    """``k`` checks over strata of ``sizes`` steps, in proportion (largest remainders first)."""
    total = sum(sizes)
    if total == 0:
        return [0] * len(sizes)
    exact = [k * s / total for s in sizes]
    got = [int(e) for e in exact]
    for i in sorted(range(len(sizes)), key=lambda i: exact[i] - got[i], reverse=True)[: k - sum(got)]:
        got[i] += 1
    return got


def verify_session(
    session: Session,
    scores: SessionScores,
    new: Sequence[LogInfo],
    truth: dict[int, np.ndarray],
    classes: Sequence[str],
    covered: Callable[[Session, LogInfo], np.ndarray],
    *,
    k: int,
    seed: int,
) -> Verified | None:
    """``k`` uniform checks of the new runs' time nobody labelled, stratified by run in proportion to that time.

    Args:
        session: The working copy after the last round.
        scores: Its scores with the final classifier.
        new: The runs that had no label at the start.
        truth: Per log id, ``(T,)`` reference index among ``classes`` (``-1``: none).
        classes: The session's terrains.
        covered: Per log, ``(T,)`` whether a step is labelled.
        k: How many checks.
        seed: Seed of the pieces' places.

    Returns:
        The estimate, or ``None`` when there is no such time.
    """
    rng = np.random.default_rng(seed)
    index = np.array([classes.index(c) for c in scores.classes])  # the model's class -> the session's
    rights, sures, kept = [], [], []
    for x in new:
        probs = scores.scores[x.id].probs
        keep = np.flatnonzero((truth[x.id] >= 0) & ~covered(session, x))
        right = index[probs.argmax(axis=1)][keep] == truth[x.id][keep]  # (K,) per step left to check
        rights.append(right.astype(np.float64))
        sures.append(np.asarray(probs.max(axis=1), np.float64)[keep])  # the model's confidence there
        kept.append(keep)
    if not sum(len(r) for r in rights):
        return None
    y, f = [], []
    for right, sure, keep, x, m in zip(rights, sures, kept, new, _allocate([len(r) for r in rights], k), strict=True):
        half = max(1, round(PIECE_S * x.rate_hz / 2))
        for centre in rng.choice(len(keep), size=min(m, len(keep)), replace=False):
            near = np.abs(keep - keep[centre]) < half  # the piece: kept steps within half a piece of its centre
            y.append(float(right[near].mean()))  # the share of the piece the model named right, as a check records
            f.append(float(sure[near].mean()))
    got = labeling.powered_accuracy(np.asarray(y), np.asarray(f), np.concatenate(sures))
    if got is None:
        return None
    truth_share = float(np.concatenate(rights).mean())
    return Verified(got.accuracy, got.low, got.high, got.checks, truth_share, float(np.mean(y)))
