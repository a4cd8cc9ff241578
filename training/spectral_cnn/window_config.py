"""How the default family's window network is fitted."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

Balance = Literal["none", "weights", "sampling", "logits"]


@dataclass(frozen=True)
class RowAugment:
    """Per-row draws of run-to-run change (0 turns one off).

    Attributes:
        gain: Spread (standard deviation) of a fast channel's log gain: ``2·ln g`` added to every bin of its log
            power spectrum, the same in every frame of the row.
        tilt: Spread of a spectral tilt: a slope across each fast channel's bins, from ``-tilt`` to ``+tilt``.
        warp: Spread of the log of a frequency scale (a speed or gait-frequency change): bins read at ``k / s``.
        level: Spread of an offset added to a slow channel's mean, minimum and maximum (normalised units).
        drop: Chance that a channel is replaced by its mean (every feature of it, every frame of the row).
        mix: Chance that a row is mixed with another row of its terrain (a convex combination, the weight uniform).
    """

    gain: float = 0.0
    tilt: float = 0.0
    warp: float = 0.0
    level: float = 0.0
    drop: float = 0.0
    mix: float = 0.0

    @property
    def active(self) -> bool:
        """Whether any draw is on."""
        return any(v > 0 for v in (self.gain, self.tilt, self.warp, self.level, self.drop, self.mix))


@dataclass(frozen=True)
class WindowFitConfig:
    """How the window classifier is fitted.

    Attributes:
        k_folds: Folds over segments; the fold models form the ensemble.
        hidden: Channels of the network's convolutions.
        epochs: Passes over the labelled rows.
        refit_epochs: Passes over labelled and pseudo-labelled rows when self-training refits.
        warm_refit: The refit goes on from the fold's first network (which labelled the stretches) rather than
            from its initial weights.
        max_steps: Most optimiser steps of one fit, whatever the data's size (bounds a Retrain on a big session).
        batch: Rows per optimiser step.
        lr: AdamW learning rate.
        weight_decay: AdamW's decoupled L2 penalty.
        noise: Standard deviation of Gaussian noise on the standardised frames while training.
        augment: Run-to-run changes drawn on each training row (:mod:`.window_augment`; off by default).
        balance: How a terrain with less labelled time keeps its weight: ``"none"`` (each row counts once),
            ``"weights"`` (the loss of a row weighted by the inverse of its terrain's share of the rows),
            ``"sampling"`` (batches drawn with each terrain equally likely) or ``"logits"`` (logit adjustment: the
            log of each terrain's share added to the logits while training, not when predicting; the default:
            on BorealTC's inner folds by run, one terrain kept at a tenth of its time, it lifted that terrain's
            recall on 6 of 6 rows, by 0.5 to 11 points, where loss weights and balanced sampling moved it less,
            ``class_balance.py``).
        self_training: Refit each fold with pseudo-labelled stretches.
        agree: Share of a stretch's frames that must agree before it is pseudo-labelled.
        unit_agree: Share of a unit's frames (its stretches together: ``units`` of the fit, the span between
            change points a stretch is a piece of) that must agree before every stretch of it takes the unit's
            terrain, whatever each says alone; 0 (the default) judges each alone. Off: at 0.6 it gained 1.9 points
            on BorealTC's inner folds by run at 10 % of labels (one terrain per run) and lost 0.4 to 3.4 on demo
            walks whose terrain changes every 5-36 s (``benchmarks/units_walks.py`` at 38a27ac).
        pool_mib: Most memory self-training's pool of unlabelled rows holds: past it, a random draw of the stretches
            that fits (``stretch_pool.pool_draw``), each read whole. A row is ``window`` frames (12.6 KiB at 22
            channels, every third frame read), so 10 hours of unlabelled logs fill 700 MiB and 100 hours 7 GiB: the
            part of a fit that grew with a fleet's hours (benchmarks/results/fleet.md). 0: no bound.
        pool_share: At most this share of the pool's bytes, drawn as ``pool_mib`` draws: what the budget keeps of a
            fleet's hours, reproduced on a small set to measure its cost (1: all).
        reference_rows: Labelled frames each member keeps for the drift score (``window_drift``): its search is
            linear in them. On BorealTC's inner folds with half the partitions labelled (so the sample binds) the
            drift told wrong predictions with AUROC 0.832 at 2,048, 0.831 at 1,024 and 0.824 at 512
            (``benchmarks/studies/drift_reference_screen.py``); 1,024 halved a rescoring's search.
        held_out: Also measure accuracy on held-out logs (folds over logs: as many fits again).
        calibrate: Divide the members' logits by a temperature fitted on held-out predictions.
        seed: Seed of the folds, initial weights and batches.
    """

    k_folds: int = 5
    hidden: int = 64
    epochs: int = 60
    refit_epochs: int = 10
    warm_refit: bool = True
    max_steps: int = 2000
    batch: int = 128
    lr: float = 3e-3
    weight_decay: float = 1e-2
    noise: float = 0.05
    augment: RowAugment = field(default_factory=RowAugment)
    balance: Balance = "logits"
    self_training: bool = True
    agree: float = 0.9
    unit_agree: float = 0.0
    pool_mib: float = 512.0
    pool_share: float = 1.0
    reference_rows: int = 1024
    held_out: bool = True
    calibrate: bool = True
    seed: int = 0
