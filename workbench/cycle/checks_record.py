"""Test then train: each label a person makes is first a check of the model they were looking at.

``record_check`` keeps what the scored classifier said on the piece (``sessions.Check``) before the label can train
anything; ``checks_summary`` reads them back as estimates (``labeling.check_estimate``): over spot checks (a fair
sample of the unlabelled time), over the checks of ranked suggestions and manual labels (where the person looked),
and per log. A ``stretch`` check (the model's own stretch accepted with ``Y``) agrees with the model by construction
and is kept but never counted.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

import labeling
from sessions import COUNTED_KINDS, Check, Session

if TYPE_CHECKING:  # the scoring path loads PyTorch; a check's record does not need it
    from .scores import SessionScores


def record_check(
    session: Session,
    scores: SessionScores,
    log_id: int,
    start: int,
    stop: int,
    terrain: str,
    *,
    kind: str,
    author: str,
) -> Check | None:
    """Keep what ``scores``' classifier said on ``[start, stop)`` of a log the person labels ``terrain``; ``None``
    (nothing kept) when the scores hold no classifier's probabilities there.

    The classifier names its classes as the terrains were called when it was trained; they are compared with the
    person's terrain by what they are called now, so a terrain renamed since is still the same terrain.
    """
    s = scores.scores.get(log_id)
    if scores.classifier is None or s is None or s.probs is None or not 0 <= start < stop <= len(s.probs):
        return None
    most, agreement = piece_answer(s.probs[start:stop], names_now(session, scores), terrain)
    return session.add_check(
        log_id,
        start,
        stop,
        terrain,
        predicted=most,
        agreement=agreement,
        classifier=scores.classifier,
        kind=kind,
        author=author,
    )


def piece_answer(probs: np.ndarray, classes: list[str], terrain: str) -> tuple[str, float]:
    """What a model said on a piece, ``(L, K)`` probabilities over ``classes``: its terrain over most of the piece,
    and the share of the piece it named ``terrain``."""
    predicted = np.asarray(probs).argmax(axis=1)  # (L,)
    most = classes[int(np.bincount(predicted, minlength=len(classes)).argmax())]
    agreement = float((predicted == classes.index(terrain)).mean()) if terrain in classes else 0.0
    return most, agreement


def names_now(session: Session, scores: SessionScores) -> list[str]:
    """The scores' class names as the session calls those terrains now (renamed since the classifier was trained, or
    not)."""
    made = next((v.created_at for v in session.model_versions("classifier") if v.id == scores.classifier), None)
    if made is None:
        return list(scores.classes)
    names = session.terrain_names_since(made)
    return [names.get(c, c) for c in scores.classes]


@dataclass(frozen=True)
class ChecksSummary:
    """The person's checks as estimates.

    Attributes:
        spot: Over spot checks: the fair one.
        suggested: Over the checks of suggestions and manual labels: where the person looked.
        all: Over every counted check.
        per_log: Per log id, over its counted checks.
        per_run: Per log name, over its counted checks: what a bundle carries of them (``checks.json``'s runs).
    """

    spot: labeling.CheckEstimate | None
    suggested: labeling.CheckEstimate | None
    all: labeling.CheckEstimate | None
    per_log: dict[int, labeling.CheckEstimate] = field(default_factory=dict)
    per_run: dict[str, labeling.CheckEstimate] = field(default_factory=dict)


def checks_summary(
    session: Session, *, log_ids: Collection[int] | None = None, classifier: int | None = None
) -> ChecksSummary:
    """The estimates of the session's checks (of ``log_ids`` only, when given; of the checks of classifier version
    ``classifier`` only, when given: evidence about that model, not the ones before it)."""
    checks = [
        c
        for c in session.checks()
        if c.kind in COUNTED_KINDS
        and (log_ids is None or c.log_id in log_ids)
        and (classifier is None or c.classifier == classifier)
    ]
    by_log: dict[int, list[bool]] = {}
    for c in checks:
        by_log.setdefault(c.log_id, []).append(c.right)
    per_log = {k: e for k, v in by_log.items() if (e := labeling.check_estimate(v)) is not None}
    return ChecksSummary(
        labeling.check_estimate([c.right for c in checks if c.kind == "spot check"]),
        labeling.check_estimate([c.right for c in checks if c.kind != "spot check"]),
        labeling.check_estimate([c.right for c in checks]),
        per_log,
    )


DISAGREE = 0.10  # the model's estimate this far from the spot checks' share, and outside their interval, is flagged


def estimate_disagrees(estimate: float | None, spot: labeling.CheckEstimate | None) -> bool:
    """Whether the model's estimate lies outside the spot checks' 95 % interval by ``DISAGREE`` or more: the spot
    checks are the fair sample of the unlabelled time, the ranked suggestions' checks run low by design."""
    if estimate is None or spot is None or abs(estimate - spot.accuracy) < DISAGREE:
        return False
    return not spot.low <= estimate <= spot.high
