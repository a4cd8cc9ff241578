"""What to expect on each file a model scores: its drift, the accuracy expected on it, and a warning when that is
well below the card's figure.

Three figures, each from what the model does on the file, with no label read:

- the members' agreement: the share of the ensemble members' pairs that name the same terrain, averaged over the
  file (:func:`labeling.member_agreement`); two members trained apart disagree about as often as each errs, so it
  estimates their accuracy there. It is the file's figure where the scoring gave it: in the loop on new runs
  (``evaluate loop``, two sessions, two seeds each, every round) it was nearer the truth than the accuracy at the
  drift in each of the four: mean distance 4.1 / 8.6 / 6.1 / 9.9 points against 7.6 / 11.1 / 7.4 / 12.1, within 5
  points on 51 of 90 runs and rounds against 37 (``benchmarks/results/raw/loop/notebook-new-runs-2026-11-28.md``).
  Like every figure without a label it cannot see a run the members all get wrong alike;
- the accuracy at its drift (:mod:`training.figures.drift_accuracy`'s relation);
- the agreement of its predictions within each stretch between change points (:func:`labeling.stretch_agreement`),
  no stretch shorter than ``SHORTEST_STRETCH_S``: where a stretch is one terrain, accuracy is at most this, and
  equal to it where the stretch's most predicted terrain is right. It cannot see a stretch the model gets wholly
  wrong, so it is printed as a bound.

The drift's figure or the stretches' 10 points or more under the card warns, and so does a file's figure that the
person's own checks in that log contradict (10 points or more away, outside their 95 % interval). The
figures measured (``benchmarks/studies/expected_borealtc.py``,
``benchmarks/results/raw/protocols/notebook-model-and-card-2026-11-27.md``) are in ``docs/model.md``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

import labeling
from training import expected_accuracy

from .cycle import estimate_disagrees

# A stretch shorter than this joins the one before it. The session's change points cut a file finely (BorealTC's
# runs, one terrain each: median 5.4 s between them), and a short stretch agrees with itself whatever the model says.
# Chosen on inner folds (BorealTC, runs within 10 points: 64/72 % at 0 s, 76/76 % at 10 s, 80/78 % at 20 s) and on
# new demo walks whose terrain changes every 5-36 s (within 10 points on 38 % of them at 0 s, 75 % at 10 s, 62 % at
# 20 s, where merging joins real changes: 38 % fell 10 points under the truth; benchmarks/studies/expected_walks.py).
SHORTEST_STRETCH_S = 10.0
BELOW_CARD = 0.10  # an expected accuracy this far under the card's figure gets a warning line
MOSTLY_DRIFTED = 0.5  # a file with more drifted time than this gets a warning line even without a relation
# fewer checks than this never contradict a figure: one wrong check has a Wilson interval of 0-79 %, so it would
# contradict any figure above 79 % although such a model is wrong on one check in five
MIN_CHECKS = 2


def card_accuracy(metrics: Mapping) -> float | None:
    """The card's headline accuracy: the estimate's (held-out logs where it could), else the held-out-log
    figure, else the out-of-fold one; ``None`` when none was measured."""
    for value in (
        (metrics.get("estimate") or {}).get("accuracy"),
        (metrics.get("held_out_logs") or {}).get("accuracy"),
        metrics.get("accuracy") if metrics.get("out_of_fold") else None,
    ):
        if value is not None and value == value:
            return float(value)
    return None


@dataclass(frozen=True)
class FileExpectation:
    """One file's drift and the accuracy expected on it.

    Attributes:
        name: The file's (log's) name.
        median_drift: The median of its steps' drift scores.
        drifted: The share of its steps with a drift score above 1.
        expected: The accuracy expected at its drift (``None`` when the model keeps no relation).
        card: The card's figure (``None`` when none was measured).
        agreement: The share of its steps predicted as their stretch's most predicted terrain (``None`` when its
            predictions and change points were not given).
        checks: The person's counted checks in this log of the model whose figure this is (a session's log;
            ``None`` for a file outside one): a check of an earlier model says little of one that learned from it.
        members: The mean of its steps' members' agreement (``None`` when the scoring gave none).
    """

    name: str
    median_drift: float
    drifted: float
    expected: float | None
    card: float | None
    agreement: float | None = None
    checks: labeling.CheckEstimate | None = None
    members: float | None = None

    @property
    def figure(self) -> float | None:
        """What the Data tab shows of the log: the members' agreement, else the accuracy at its drift, else the
        bound by its stretches."""
        for value in (self.members, self.expected, self.agreement):
            if value is not None:
                return value
        return None

    @property
    def checks_disagree(self) -> bool:
        """Whether the person's checks in the log (``MIN_CHECKS`` or more) contradict its figure, by the rule the
        card is held against the spot checks with (``cycle.estimate_disagrees``: 10 points or more away from their
        share right and outside their 95 % interval)."""
        c = self.checks
        return c is not None and c.n >= MIN_CHECKS and estimate_disagrees(self.figure, c)

    @property
    def below_card(self) -> bool:
        """Whether the expected accuracy is ``BELOW_CARD`` or more under the card's figure."""
        return self.expected is not None and self.card is not None and self.card - self.expected >= BELOW_CARD - 1e-9

    @property
    def disagrees(self) -> bool:
        """Whether its predictions' agreement within stretches is ``BELOW_CARD`` or more under the card's figure."""
        return self.agreement is not None and self.card is not None and self.card - self.agreement >= BELOW_CARD - 1e-9

    def figures(self) -> str | None:
        """``"expected accuracy 80 % at its drift, at most 88 % by its stretches (the card: 82 %)"``; ``None``
        when neither figure exists."""
        figures = [  # by its stretches is an upper bound where each stretch is one terrain: it reads as one
            *([] if self.members is None else [f"{self.members:.0%} by its members' agreement"]),
            *([] if self.expected is None else [f"{self.expected:.0%} at its drift"]),
            *([] if self.agreement is None else [f"at most {self.agreement:.0%} by its stretches"]),
        ]
        if not figures:
            return None
        card = f" (the card: {self.card:.0%})" if self.card is not None else ""
        return f"expected accuracy {', '.join(figures)}{card}"

    def line(self) -> str:
        """``"walk3.csv: median drift 0.62, 8 % of it above 1; expected accuracy 80 % at its drift, at most 88 % by
        its stretches (the card: 82 %)"``."""
        head = f"{self.name}: median drift {self.median_drift:.2f}, {self.drifted:.0%} of it above 1"
        figures = self.figures()
        return head if figures is None else f"{head}; {figures}"

    def warning(self) -> str | None:
        """One line when the person's checks in the log contradict its figure, when the file is expected to score
        well below the card, or (with no relation) is mostly drifted; else ``None``."""
        if self.checks_disagree:
            bound = self.members is None and self.expected is None  # the figure is the stretches' bound
            what = "its stretches bound its accuracy at" if bound else "expected accuracy"
            return (
                f"warning: {self.name}: {what} {self.figure:.0%}, but your checks of this model in it found it "
                f"{self.checks.words()}: trust the checks; label more of it and retrain"  # type: ignore[union-attr]
            )
        if self.below_card:
            points = _points(self.card, self.expected)  # type: ignore[arg-type]
            return (
                f"warning: {self.name}: expected accuracy {self.expected:.0%}, {points} points below the "
                f"card's {self.card:.0%}: it is unlike anything labelled (median drift {self.median_drift:.2f}); "
                "label some of it and retrain"
            )
        if self.disagrees:
            points = _points(self.card, self.agreement)  # type: ignore[arg-type]
            return (
                f"warning: {self.name}: its predictions agree with their stretch's terrain on {self.agreement:.0%} "
                f"of it, {points} points below the card's {self.card:.0%}: the model changes its mind where the "
                "signals do not; label some of it and retrain"
            )
        if self.expected is None and self.drifted > MOSTLY_DRIFTED:
            return (
                f"warning: {self.name}: {self.drifted:.0%} of its time is unlike anything labelled "
                "(drift > 1): its predictions are less reliable there; label some of it and retrain"
            )
        return None


def _points(card: float, figure: float) -> int:
    """Points between two figures as the line prints them (whole percents), so the difference reads true."""
    return round(100 * card) - round(100 * figure)


def file_expectation(
    name: str,
    drift: np.ndarray | None,
    metrics: Mapping,
    *,
    predicted: np.ndarray | None = None,
    change_points: np.ndarray | None = None,
    rate_hz: float | None = None,
    checks: labeling.CheckEstimate | None = None,
    members: np.ndarray | None = None,
    labelled: Sequence[tuple[int, int]] = (),
) -> FileExpectation | None:
    """A file's expectation; ``None`` without drift.

    Args:
        name: The file's (log's) name.
        drift: Its steps' drift scores ``(T,)``.
        metrics: The classifier's metrics (the card's figure, the drift relation).
        predicted: Its steps' predicted terrains ``(T,)``; with ``change_points``, the agreement within stretches.
        change_points: Its change points (sample indices), as the session finds them.
        rate_hz: Its sample rate; with ``predicted`` and ``change_points``, the agreement within stretches.
        checks: The person's checks in it, where it is a session's log (``cycle.checks_summary``'s ``per_log``).
        members: Its steps' members' agreement ``(T,)`` (``labeling.LogScores.agreement``), where the scoring gave it.
        labelled: Its labelled spans ``(start, stop)``, left out of the members' figure: what is expected is the
            accuracy where the person has not said the terrain (a session's log; the loop's labels are where the
            members doubted, and a short run's few seconds of them moved its figure by 2.5 points).
    """
    share = labeling.drifted_share(drift)
    if share is None:
        return None
    card = card_accuracy(metrics)
    expected = expected_accuracy(metrics.get("drift_accuracy"), drift)
    agreement = None
    if predicted is not None and change_points is not None and rate_hz is not None:
        agreement = stretch_share(predicted, change_points, rate_hz=rate_hz)
    mean_agreement = None
    if members is not None:
        free = np.ones(len(members), bool)
        for a, b in labelled:
            free[a:b] = False
        if free.any():
            mean_agreement = float(np.mean(members[free], dtype=np.float64))
    return FileExpectation(name, float(np.median(drift)), share, expected, card, agreement, checks, mean_agreement)


def stretch_share(predicted: np.ndarray, change_points: np.ndarray, *, rate_hz: float) -> float | None:
    """The share of a file's steps predicted ``(T,)`` as their stretch's most predicted terrain, the stretches cut
    at its ``change_points`` with none shorter than ``SHORTEST_STRETCH_S``; ``None`` for no steps."""
    points = labeling.coarser_points(change_points, len(predicted), round(SHORTEST_STRETCH_S * rate_hz))
    return labeling.stretch_agreement(predicted, points)
