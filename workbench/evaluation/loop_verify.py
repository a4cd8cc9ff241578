"""Verification checks in the loop, before the first round and after each: uniform pieces of the new runs' time
nobody labelled, drawn as ``workbench suggest --verify`` draws them (stratified by run), checked by the reference as
a person would, as spot checks of that round's model; never labelled, never recorded (the rounds' suggestions read
the session's checks), counted apart from the rounds' suggestions.

The figures are then what the workbench itself shows (``cycle.FigureTally``, the path of the status line's figure
for the session and the Data tab's per run), set beside the truth over the same time: whether each 90 % interval
covers it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

import labeling
from sessions import Check, LogInfo, Session

from ..cycle import FigureTally, SessionFigure, SessionScores, names_now, piece_answer, suggestion_lengths

AUTHOR = "verify"


@dataclass(frozen=True)
class Verified:
    """The workbench's figures after the verification checks, beside the truth.

    Attributes:
        accuracy: The session's estimate.
        low: Its 90 % interval's lower bound.
        high: Its upper bound.
        checks: How many checks it rests on.
        truth: The accuracy the reference gives the same time.
        checks_right: The checks' mean share of steps named right (the checks alone).
        per_run: Per new run's name, ``(estimate, low, high, checks, truth)`` (``None`` figures: not checked).
    """

    accuracy: float
    low: float
    high: float
    checks: int
    truth: float
    checks_right: float
    per_run: dict[str, tuple[float | None, float | None, float | None, int, float]] = field(default_factory=dict)

    @property
    def covers(self) -> bool:
        """Whether the interval holds the truth."""
        return self.low - 1e-9 <= self.truth <= self.high + 1e-9

    def runs_covered(self) -> tuple[int, int]:
        """``(covered, checked)`` over the runs with a figure."""
        got = [r for r in self.per_run.values() if r[0] is not None]
        return sum(r[1] - 1e-9 <= r[4] <= r[2] + 1e-9 for r in got), len(got)  # type: ignore[operator]


def _truth_share(scores: SessionScores, x: LogInfo, truth: np.ndarray, free: np.ndarray, classes: Sequence[str]):
    index = np.array([classes.index(c) for c in scores.classes])  # the model's class -> the session's
    keep = free & (truth >= 0)
    right = index[np.asarray(scores.scores[x.id].probs).argmax(axis=1)][keep] == truth[keep]
    return right, int(keep.sum())


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
    """``k`` uniform checks of the new runs' time nobody labelled, stratified by run in proportion to that time, as
    spot checks of ``scores``' classifier (in memory only: nothing is recorded or labelled).

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
        The figures beside the truth, or ``None`` when there is no such time or no check could be made.
    """
    free = {x.id: ~covered(session, x) for x in new}
    rights = {x.id: _truth_share(scores, x, truth[x.id], free[x.id], classes)[0] for x in new}
    if not sum(len(r) for r in rights.values()):
        return None
    max_len, min_len = suggestion_lengths(new[0].rate_hz, span=scores.span)
    labelled = [(i, g.start, g.stop) for i, x in enumerate(new) for g in session.segments(x.id)]
    pieces = labeling.verification_checks(
        [x.n_samples for x in new], labelled, k, max_len=max_len, min_len=min_len, seed=seed
    )
    names = names_now(session, scores)
    checks, ys = [], []
    for p in pieces:
        x = new[p.log]
        ref = truth[x.id][p.start : p.stop]
        ref = ref[ref >= 0]
        if not len(ref):
            continue  # no reference there: a person would skip it
        terrain = classes[int(np.bincount(ref).argmax())]
        most, agreement = piece_answer(scores.scores[x.id].probs[p.start : p.stop], names, terrain)  # as recorded
        checks.append(
            Check(0, x.id, p.start, p.stop, terrain, most, agreement, scores.classifier, "spot check", AUTHOR, "")
        )
        ys.append(agreement)
    if scores.classifier is None or not checks:
        return None
    tally = FigureTally(session, scores.classifier, checks=checks)
    for x in new:
        tally.add(x.id, scores.scores[x.id].probs)
    figures = tally.figures()
    whole: SessionFigure = figures.session
    if whole.figure is None:
        return None
    per_run = {}
    for x in new:
        f = figures.per_log.get(x.id)
        got = None if f is None else f.figure
        share = float(rights[x.id].mean()) if len(rights[x.id]) else float("nan")
        per_run[x.name] = (
            None if got is None else got.accuracy,
            None if got is None else got.low,
            None if got is None else got.high,
            0 if got is None else got.checks,
            share,
        )
    f = whole.figure
    truth_share = float(np.concatenate(list(rights.values())).mean())
    return Verified(f.accuracy, f.low, f.high, f.checks, truth_share, float(np.mean(ys)), per_run)
