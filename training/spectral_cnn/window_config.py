"""How the default family's window network is fitted."""

from __future__ import annotations

from dataclasses import dataclass, field

from .window_augment import RowAugment


@dataclass(frozen=True)
class WindowFitConfig:
    """How the window classifier is fitted.

    Attributes:
        k_folds: Folds over segments; the fold models form the ensemble.
        hidden: Channels of the network's convolutions.
        epochs: Passes over the labelled rows.
        refit_epochs: Passes over labelled and pseudo-labelled rows when self-training refits.
        max_steps: Most optimiser steps of one fit, whatever the data's size (bounds a Retrain on a big session).
        batch: Rows per optimiser step.
        lr: AdamW learning rate.
        weight_decay: AdamW's decoupled L2 penalty.
        noise: Standard deviation of Gaussian noise on the standardised frames while training.
        augment: Run-to-run changes drawn on each training row (:mod:`.window_augment`; off by default).
        self_training: Refit each fold with pseudo-labelled stretches.
        agree: Share of a stretch's frames that must agree before it is pseudo-labelled.
        held_out: Also measure accuracy on held-out logs (folds over logs: as many fits again).
        calibrate: Divide the members' logits by a temperature fitted on held-out predictions.
        seed: Seed of the folds, initial weights and batches.
    """

    k_folds: int = 5
    hidden: int = 64
    epochs: int = 60
    refit_epochs: int = 30
    max_steps: int = 2000
    batch: int = 128
    lr: float = 3e-3
    weight_decay: float = 1e-2
    noise: float = 0.05
    augment: RowAugment = field(default_factory=RowAugment)
    self_training: bool = True
    agree: float = 0.9
    held_out: bool = True
    calibrate: bool = True
    seed: int = 0
