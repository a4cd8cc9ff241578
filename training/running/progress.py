"""Progress reports and cancellation, so a UI or CLI can drive training and stop it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


class Cancelled(Exception):
    """Training was cancelled; nothing was saved."""


@dataclass(frozen=True)
class Progress:
    """Where a training run is. ``fraction`` is of the whole run, assuming it goes to ``max_epochs``."""

    stage: str  # "predictor" | "classifier"
    fold: int  # 0 for stage 1; 1..k for stage-2 folds
    folds: int
    epoch: int
    max_epochs: int
    step: int
    steps: int  # per epoch
    train_loss: float
    val_loss: float | None
    best_val_loss: float | None
    elapsed_s: float

    @property
    def fraction(self) -> float:
        per_fold = ((self.epoch - 1) + self.step / max(self.steps, 1)) / max(self.max_epochs, 1)
        return min(1.0, ((max(self.fold, 1) - 1) + per_fold) / max(self.folds, 1))


ProgressFn = Callable[[Progress], None]
CancelFn = Callable[[], bool]


def never() -> bool:
    return False
