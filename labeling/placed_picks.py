"""What a suggestion is, and the picks placed apart from the ranking: each new log's main answer (first) and the spot
checks (last). The time nobody labelled (``coverage``, ``unlabelled_runs``) is where every pick may go.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .tracks import LogScores, smooth

Span = tuple[int, int, int]  # (log, start, stop) in samples


@dataclass(frozen=True)
class Suggestion:
    """A segment to label next.

    Attributes:
        log: Log index.
        start: First sample.
        stop: One past the last sample.
        score: The strategy's score after diversity (higher first).
        reason: Why, in words a person reads in the UI.
        guess: The model's most probable class over the segment, or ``None`` before a classifier exists.
        rank: 0 for the first suggestion.
        kind: ``"suggestion"`` (ranked: where the model is unsure, drifted, or a log nobody checked), ``"spot
            check"`` (drawn uniformly over the unlabelled time: the person's check of it is a fair sample of how the
            model does there) or ``"main answer"`` (the middle of the model's longest stretch of one terrain in a log
            nobody checked: whether the bulk of that run is what the model says).
    """

    log: int
    start: int
    stop: int
    score: float
    reason: str
    guess: int | None
    rank: int
    kind: str = "suggestion"


def unlabelled_runs(start: int, stop: int, covered: np.ndarray, *, min_len: int) -> list[tuple[int, int]]:
    """The parts of ``[start, stop)`` where ``covered`` (``(T,)`` bool) is false, at least ``min_len`` long."""
    free = ~covered[start:stop]
    if not free.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], free.astype(np.int8), [0]])))
    return [(start + int(a), start + int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= min_len]


MISSES_BEFORE_LOOKING = 64  # draws in a row that found no piece before the free time is searched for room


def _room_left(cov: Sequence[np.ndarray], min_len: int) -> bool:
    """Whether some log still has a run of at least ``min_len`` steps that is not covered."""
    return any(unlabelled_runs(0, len(c), c, min_len=min_len) for c in cov)


def coverage(lengths: Sequence[int], labelled: Sequence[Span]) -> list[np.ndarray]:
    """Per log, ``(T,)`` bool: true where labelled."""
    cov = [np.zeros(n, bool) for n in lengths]
    for log, a, b in labelled:
        cov[log][max(a, 0) : max(b, 0)] = True
    return cov


def main_answers(
    scores: Sequence[LogScores],
    skip: set[int],
    classes: Sequence[str],
    covered: Sequence[np.ndarray],
    *,
    window: int,
    min_len: int,
) -> list[Suggestion]:
    """Per log not in ``skip``, a piece of up to ``window`` samples at the middle of the model's longest run of one
    terrain (the probabilities smoothed over ``window``), or in that run's unlabelled part nearest its middle
    (``covered``: per log, ``(T,)`` true where labelled; none at least ``min_len`` long: no piece); the longest runs
    first (ties by log)."""
    out = []
    for g, s in enumerate(scores):
        if g in skip or s.probs is None or len(s.probs) < window:
            continue
        probs = np.asarray(s.probs, np.float64)
        label = np.stack([smooth(probs[:, j], window) for j in range(probs.shape[1])], axis=1).argmax(axis=1)  # (T,)
        edges = np.flatnonzero(np.diff(label)) + 1
        begin, end = np.r_[0, edges], np.r_[edges, len(label)]
        i = int(np.argmax(end - begin))
        middle = (int(begin[i]) + int(end[i])) // 2
        free = unlabelled_runs(int(begin[i]), int(end[i]), covered[g], min_len=min_len)
        if not free:
            continue
        a, b = min(free, key=lambda r: 0 if r[0] <= middle < r[1] else min(abs(r[0] - middle), abs(r[1] - 1 - middle)))
        start = int(np.clip(min(max(middle, a), b - 1) - window // 2, a, max(a, b - window)))
        stop = min(b, start + window)
        k = int(label[begin[i]])
        share = (end[i] - begin[i]) / len(label)
        name = classes[k] if k < len(classes) else f"class {k}"
        reason = f"the model's main answer in this log: {name} over {100 * share:.0f} % of it in one stretch"
        guess = int(probs[start:stop].mean(axis=0).argmax())
        out.append(Suggestion(g, start, stop, float(share), reason, guess, 0, "main answer"))
    return sorted(out, key=lambda x: (-x.score, x.log))


SPOT_REASON = "spot check: a piece drawn at random from the unlabelled time, so the estimate from your checks is fair"


def spot_guess(scores: Sequence[LogScores], spot: Suggestion) -> int | None:
    """The model's most probable class over a spot check's piece, ``None`` before a classifier exists."""
    probs = scores[spot.log].probs
    return None if probs is None else int(np.asarray(probs[spot.start : spot.stop]).mean(axis=0).argmax())


def spot_checks(
    lengths: Sequence[int],
    labelled: Sequence[Span],
    taken: Sequence[Span],
    count: int,
    *,
    max_len: int,
    min_len: int,
    seed: int,
) -> list[Suggestion]:
    """``count`` pieces of up to ``max_len`` around steps drawn uniformly from the time neither labelled nor taken
    (a piece that would be shorter than ``min_len`` there is drawn again, at most 50 times each)."""
    if count <= 0:
        return []
    cov = coverage(lengths, [*labelled, *taken])
    rng = np.random.default_rng([seed, 65])
    out: list[Suggestion] = []
    # the unlabelled steps of every log, counted per log: the n-th of them all is drawn without listing them (a
    # fleet's hours of steps as one index were 300 MB, copied after each pick)
    free = np.array([len(c) - int(np.count_nonzero(c)) for c in cov], np.int64)
    misses = 0
    for _ in range(50 * count):
        if len(out) == count or not free.sum():
            break
        if misses and misses % MISSES_BEFORE_LOOKING == 0 and not _room_left(cov, min_len):
            break  # no free run a piece fits in: more draws would all miss (a count past what the time holds)
        at = int(rng.integers(free.sum()))
        before = np.cumsum(free)
        log = int(np.searchsorted(before, at, side="right"))
        step = int(np.flatnonzero(~cov[log])[at - (int(before[log]) - int(free[log]))])
        a, b = max(0, step - max_len // 2), min(lengths[log], step - max_len // 2 + max_len)
        pieces = [(x, y) for x, y in unlabelled_runs(a, b, cov[log], min_len=min_len) if x <= step < y]
        if not pieces:
            misses += 1
            continue
        misses = 0
        x, y = pieces[0]
        cov[log][x:y] = True
        free[log] -= y - x
        out.append(Suggestion(log, x, y, 0.0, SPOT_REASON, None, len(out), "spot check"))
    return out
