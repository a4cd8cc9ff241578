"""``evaluate loop``'s arms: each a queue policy (the page's, with one lever changed) and how its scores and fits
are made, so what an arm measures is the page's own queue with that lever left out."""

from __future__ import annotations

from dataclasses import dataclass, replace

import labeling

from ..cycle import SESSION_POLICY
from ..retrain import RETRAIN


@dataclass(frozen=True)
class LoopArm:
    """What one arm of the loop runs: the page's queue policy, and how its scores and fits are made.

    Attributes:
        policy: The suggestion queue's policy (the session's, ``cycle.SESSION_POLICY``, with a lever changed).
        votes: Whether a run's labels vote over its frames in the scores (``compute_scores(votes=)``).
        teach: Whether each round's fit is taught by the session's scores (``RETRAIN.teach``).
        teach_last: Whether the last round's fit alone is taught so and made the session's active version.
        ships_taught: Whether the far runs are scored by the model ``export`` ships (the round's fit taught by the
            session, kept beside it; the session goes on with its own) or by the round's fit as it is.
        teach_passes: Taught fits in a row for the model that ships (``cycle.shipped_version``'s ``passes``).
    """

    policy: labeling.QueuePolicy = SESSION_POLICY
    votes: bool = True
    teach: bool = RETRAIN.teach
    teach_last: bool = False
    ships_taught: bool = True
    teach_passes: int = 1


# What a lever is worth, measured by leaving it out: an arm's name in the loop -> what it runs
ABLATIONS: dict[str, LoopArm] = {
    "combined-no-unchecked": LoopArm(replace(SESSION_POLICY, unchecked_first=False)),  # new runs not checked first
    "combined-no-votes": LoopArm(votes=False),  # a run's labels not carried over its frames
    "combined-no-wrong-first": LoopArm(replace(SESSION_POLICY, wrong_first=False)),  # wrong runs not asked again
    "combined-no-main-answer": LoopArm(replace(SESSION_POLICY, main_answer="off")),  # a run's main answer never asked
    "combined-main-answer-new": LoopArm(replace(SESSION_POLICY, main_answer="new")),  # every new run's asked first
    "combined-teacher": LoopArm(teach=True),  # the fit taught by the session's scores (RETRAIN.teach)
    "combined-teacher-last": LoopArm(teach_last=True),  # the last round's fit alone taught so
    "combined-untaught": LoopArm(ships_taught=False),  # the far runs scored by the round's fit, not the taught one
    "combined-taught-twice": LoopArm(teach_passes=2),  # taught again from the taught model's scores of the session
}


def loop_arm(name: str) -> LoopArm:
    """The arm a strategy's name stands for: an ablation of ``ABLATIONS``, or the session's queue with that strategy
    (``labeling.STRATEGIES``)."""
    if name in ABLATIONS:
        return ABLATIONS[name]
    return LoopArm(replace(SESSION_POLICY, strategy=name))  # type: ignore[arg-type]
