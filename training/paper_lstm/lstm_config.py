"""Configs of the two stages and of training, with the paper's values as defaults.

Paper (Kumar et al., "Loss Regularizing Robotic Terrain Classification"): two stacked 200-unit LSTMs, elastic-net
regularised MSE (stage 1) and cross-entropy (stage 2), Adam with learning rate 0.005, batch 512, dropout 20 %,
up to 300 epochs, k-fold validation with k = 5, inputs normalised to zero mean and unit variance. The paper gives
no values for the elastic net's λ and γ; ours are documented where they are set.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

FeatureMode = Literal["hidden", "estimate", "error", "hidden+error", "surprise", "hidden+surprise"]
FEATURE_MODES: tuple[FeatureMode, ...] = ("hidden", "estimate", "error", "hidden+error", "surprise", "hidden+surprise")


@dataclass(frozen=True)
class ElasticNet:
    """``λ(γ·Σ|θ| + (1−γ)·Σθ²)`` over an LSTM's W, U and B.

    λ is small because the penalty is a *sum* over ~180 k weights while the data term is a *mean*; 1e-6 puts the
    penalty near 1 % of the stage-1 loss of a trained 200-unit model.
    """

    lam: float = 1e-6
    gamma: float = 0.5


@dataclass(frozen=True)
class PredictorConfig:
    """Stage 1: an LSTM estimating each sample from the ones before it, with a linear head."""

    n_channels: int
    hidden: int = 200


@dataclass(frozen=True)
class ClassifierConfig:
    """Stage 2: an LSTM on stage-1 features, 20 % dropout after each LSTM layer, a linear layer and softmax."""

    n_features: int
    n_classes: int
    hidden: int = 200
    dropout: float = 0.2
    kind: str = "lstm"  # names this family's module in a bundle's config (older bundles lack it: the same)


@dataclass(frozen=True)
class TrainConfig:
    """How a stage is trained.

    Attributes:
        lr: Adam's learning rate.
        batch_size: Sequences (pieces of logs or labelled segments) per optimiser step.
        max_epochs: Upper bound; early stopping on validation loss usually ends sooner.
        patience: Epochs without a better validation loss before stopping.
        chunk: Truncated-BPTT length; the LSTM state is carried from chunk to chunk within a piece.
        piece: Longest piece a log is cut into for stage 1 (longer logs become several pieces).
        context: Stage 2: unlabelled samples before each labelled piece that run the classifier's state (no loss
            there). At inference the classifier runs over whole logs with its state carried; trained on short
            pieces from a zero state it never learns to forget, and a whole-log pass drifts (measured on a toy
            problem: 55 % with a context of 8 samples, 90 % with 100).
        label_piece: Stage 2: longest labelled stretch in one training sequence (longer segments are cut).
        clip: Gradient-norm clipping (not in the paper; LSTMs at lr 0.005 diverge now and then without it).
        val_fraction: Stage 1: share of pieces held out for early stopping (the paper's 80/20 split).
        k_folds: Stage 2: folds over labelled segments; the fold models form the ensemble.
        class_balance: Stage 2: weight each class's cross-entropy by the inverse of its labelled steps (the
            weights' labelled-step mean is 1), so a terrain labelled less does not lose to one labelled more. Off by
            default: on BorealTC's label-efficiency simulation (3 seeds) it left random labelling's curve where it
            was and lowered the suggested labels' middle rounds by 3 points
            (benchmarks/results/raw/protocols/notebook-label-efficiency-2026-11-26.md).
        consistency: Stage 2: weight of the consistency term on unlabelled neighbour pairs (``fit_classifier``'s
            ``pairs``): the squared distance between the class probabilities the model gives two windows of one log
            a few seconds apart, with no change point between their last steps. It lets the unlabelled logs shape the
            classifier, which counts most when labels are few: on BorealTC, 40 partitions chosen by ``combined`` went
            from 78.7 to 83.7 % with weight 3 (fold 2;
            benchmarks/results/raw/protocols/notebook-label-efficiency-2026-11-26.md). Ignored without pairs.
            Off (0) by default: on 40 minutes of demo walks it made the UI's stage-2 refit from scratch 15× slower
            (1356 s against 90 s) for no accuracy (71.2 against 72.6 %; benchmarks/paper_consistency_cost.py at
            38a27ac), and on BorealTC's simulation it moved the label-efficiency ratio from about 0.73× to 0.68×
            only (8 seeds).
        elastic: The elastic-net penalty.
        seed: Seed of every random choice.
        device: "cpu" or "cuda".
        bf16: On CUDA, run the LSTMs under bfloat16 autocast (losses and weights stay float32); ignored on CPU.
    """

    lr: float = 0.005
    batch_size: int = 512
    max_epochs: int = 300
    patience: int = 20
    chunk: int = 128
    piece: int = 1024
    context: int = 300
    label_piece: int = 400
    val_fraction: float = 0.2
    clip: float = 1.0
    k_folds: int = 5
    class_balance: bool = False
    consistency: float = 0.0
    elastic: ElasticNet = ElasticNet()
    seed: int = 0
    device: str = "cpu"
    bf16: bool = True
