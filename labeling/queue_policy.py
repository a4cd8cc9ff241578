"""What a suggestion queue is asked: its policy (which tiers, in which order, how long a pick, how many spot checks)
and the evidence it ranks with (what is labelled, what the person's checks found, the model's recalls).

A new idea for the queue is a new :class:`QueuePolicy` field with its test; ``evaluate loop``'s arms are policies.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .placed_picks import Span
from .tracks import Kind

Strategy = Literal["random", "entropy", "margin", "disagreement", "surprise", "combined"]
MainAnswer = Literal["off", "new", "checked-right"]  # which logs are asked the model's main answer there
STRATEGIES: tuple[Strategy, ...] = ("random", "entropy", "margin", "disagreement", "surprise", "combined")


@dataclass(frozen=True)
class QueuePolicy:
    """How the queue ranks and places its picks.

    Attributes:
        strategy: ``random``, ``entropy``, ``margin``, ``disagreement`` (BALD), ``surprise`` or ``combined``.
        max_len: Longest pick, samples.
        min_len: Shortest pick, samples.
        window: Smoothing of the tracks, samples.
        seed: Seed of ``random``, of the clustering and of the spot checks (the rest is deterministic; ties break by
            log then start).
        unchecked_first: ``combined``: the candidates of logs with no labelled span come before every other one,
            spread over those logs and then over their time, so a person's new runs are checked before more time of
            runs already checked.
        wrong_first: ``combined`` (with ``unchecked_first``): a checked log is lifted by ``wrong / (checks + 1)`` of
            the new logs' tier, from :attr:`Evidence.wrong`: where checks found the model wrong, more checks follow,
            behind the logs nobody has checked yet. Off only to measure what it is worth.
        main_answer: ``combined`` (with ``unchecked_first``): where a log is asked about its main answer, the middle
            of the model's longest stretch of one terrain (kind ``"main answer"``, placed first): a run the model
            reads confidently as the wrong terrain has no doubt to draw a pick to its bulk. ``"new"``: every log
            nobody checked. ``"checked-right"``: a log once the person's checks there found the model right at least
            as often as wrong (where it is wrong there, the tier goes on asking where it doubts). ``"off"``: never.
        spot_checks: How many of the ``n`` are spot checks, placed last: each a piece around a step drawn uniformly
            from the unlabelled time, overlapping neither labels nor the other picks. A check of one is an unbiased
            sample of the model's accuracy on unlabelled time, which a ranked pick's is not.
    """

    strategy: Strategy = "combined"
    max_len: int = 500
    min_len: int = 100
    window: int = 25
    seed: int = 0
    unchecked_first: bool = True
    wrong_first: bool = True
    main_answer: MainAnswer = "off"
    spot_checks: int = 0


@dataclass(frozen=True, eq=False)
class Evidence:
    """What the queue knows besides the scores: per log, in the order of the scores.

    Attributes:
        labelled: Labelled stretches ``(log, start, stop)``; never suggested again.
        label_counts: ``(K,)`` labelled samples per class (``combined`` favours rare classes).
        change_points: Per log, ``(N,)`` change-point sample indices where candidates are cut.
        classes: ``K`` class names, for the reasons.
        embeddings: Per log, ``(T, D)`` features (e.g. stage 1's hidden state), or objects that answer their spans'
            means (``segment_means``). ``combined`` clusters the candidates' mean feature vectors and takes the most
            typical member of each cluster first, holding back segments like labelled ones: before a classifier
            exists this alone ranks (covering the kinds of terrain), after it the clusters keep the picks diverse.
        recall: ``(K,)`` each class's measured recall (NaN: not measured). ``combined`` favours candidates the model
            gives some probability to a class it misses (recall under ``MISSED_RECALL``): a missed terrain is rarely
            the guess, so its probability, not the guess, says where it may be; the reason names it.
        wrong: Per log, ``(wrong, checks)``: how often the person's checks there found the model wrong (read by
            :attr:`QueuePolicy.wrong_first` and ``main_answer="checked-right"``).
        answered: The pieces of ``labelled`` that were checks of a log's main answer: they do not count as checking
            the log, and a log with one is not asked its main answer again.
        tracks: Per log, the tracks ``normalised_tracks`` gives for these scores and the policy's window, where the
            caller has them already: the kinds the strategy reads are taken from them instead of computed again (at
            10 hours of logs, 69 MB).
    """

    labelled: Sequence[Span] = ()
    label_counts: np.ndarray | None = None
    change_points: Sequence[np.ndarray] | None = None
    classes: Sequence[str] = ()
    embeddings: Sequence[np.ndarray] | None = None
    recall: np.ndarray | None = None
    wrong: Sequence[tuple[int, int]] | None = None
    answered: Sequence[Span] = ()
    tracks: Sequence[Mapping[Kind, np.ndarray]] | None = None
