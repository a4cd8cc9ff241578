"""What to expect on each file a model scores: its drift, the accuracy expected at that drift, and a warning when
that is well below the card's figure (issue 54; the relation is :mod:`training.drift_accuracy`'s)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

import labeling
from training import expected_accuracy

BELOW_CARD = 0.10  # an expected accuracy this far under the card's figure gets a warning line
MOSTLY_DRIFTED = 0.5  # a file with more drifted time than this gets a warning line even without a relation


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
    """

    name: str
    median_drift: float
    drifted: float
    expected: float | None
    card: float | None

    @property
    def below_card(self) -> bool:
        """Whether the expected accuracy is ``BELOW_CARD`` or more under the card's figure."""
        return self.expected is not None and self.card is not None and self.card - self.expected >= BELOW_CARD - 1e-9

    def line(self) -> str:
        """``"walk3.csv: median drift 0.62, 8 % of it above 1; expected accuracy 80 % (the card: 82 %)"``."""
        head = f"{self.name}: median drift {self.median_drift:.2f}, {self.drifted:.0%} of it above 1"
        if self.expected is None:
            return head
        card = f" (the card: {self.card:.0%})" if self.card is not None else ""
        return f"{head}; expected accuracy {self.expected:.0%}{card}"

    def warning(self) -> str | None:
        """One line when the file is expected to score well below the card, or (with no relation) is mostly
        drifted; else ``None``."""
        if self.below_card:
            points = 100 * (self.card - self.expected)  # type: ignore[operator]
            return (
                f"warning: {self.name}: expected accuracy {self.expected:.0%}, {points:.0f} points below the "
                f"card's {self.card:.0%}: it is unlike anything labelled (median drift {self.median_drift:.2f}); "
                "label some of it and retrain"
            )
        if self.expected is None and self.drifted > MOSTLY_DRIFTED:
            return (
                f"warning: {self.name}: {self.drifted:.0%} of its time is unlike anything labelled "
                "(drift > 1): its predictions are less reliable there; label some of it and retrain"
            )
        return None


def file_expectation(name: str, drift: np.ndarray | None, metrics: Mapping) -> FileExpectation | None:
    """A file's expectation from its steps' drift ``(T,)`` and the model's metrics; ``None`` without drift."""
    share = labeling.drifted_share(drift)
    if share is None:
        return None
    card = card_accuracy(metrics)
    expected = expected_accuracy(metrics.get("drift_accuracy"), drift)
    return FileExpectation(name, float(np.median(drift)), share, expected, card)
