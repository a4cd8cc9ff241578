"""A second model scored beside the default family in the BorealTC window protocol, alone and averaged with it:
how a family (MiniRocket) and an ensemble member are measured on the same folds, labels and test windows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FoldData:
    """What a member sees of one outer fold.

    Attributes:
        fold: The outer fold (1-based).
        train: The fold's training partitions, normalised ``(T, C)`` each.
        y: Each training partition's terrain.
        labelled: Indices into ``train`` of the labelled partitions.
        runs: Each training partition's run.
        test: The test windows, normalised ``(N, L, C)``.
        n_classes: Terrains.
        seed: The protocol's seed.
    """

    fold: int
    train: list[np.ndarray]
    y: np.ndarray
    labelled: np.ndarray
    runs: np.ndarray
    test: np.ndarray
    n_classes: int
    seed: int


Member = Callable[[FoldData], np.ndarray]  # -> (N, K) probabilities of the test windows


def cut_windows(parts: list[np.ndarray], length: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Every ``length``-sample window at ``stride`` of each partition: ``(N, L, C)`` and the partition of each."""
    out, owner = [], []
    for i, p in enumerate(parts):
        for start in range(0, len(p) - length + 1, stride):
            out.append(p[start : start + length])
            owner.append(i)
    return np.asarray(out, np.float32), np.asarray(owner, np.int64)


@dataclass
class RocketMember:
    """MiniRocket and a ridge head (``training.fit_rocket_classifier``): the transform's biases from every training
    partition (no labels read, as stage 1 reads every log), the head on the labelled partitions' windows at
    ``stride`` samples, its temperature on held-out runs.

    The transform of a fold's test windows does not depend on the labels, so it is kept per fold and reused when the
    same folds run again at another labelled share.
    """

    stride: int = 50
    features: int = 10_000
    biases_from: str = "all"  # "all": every training partition; "labelled": the labelled ones (aeon's pipeline)

    def __post_init__(self) -> None:
        self._test: dict[int, tuple[dict, np.ndarray]] = {}  # fold -> (the transform's buffers, test features)

    def __call__(self, data: FoldData) -> np.ndarray:
        import torch

        from training import fit_rocket_classifier, rocket_features

        length = data.test.shape[1]
        windows, owner = cut_windows([data.train[i] for i in data.labelled], length, self.stride)
        pool = None
        if self.biases_from == "all":
            pool, _ = cut_windows(data.train, length, self.stride)
        model = fit_rocket_classifier(
            windows,
            data.y[data.labelled][owner],
            data.n_classes,
            unlabelled=pool,
            groups=data.runs[data.labelled][owner],
            features=self.features,
            seed=data.seed + data.fold,
        )
        state = model.transform.state_dict()
        cached = self._test.get(data.fold)
        if cached is None or not _same(cached[0], state) or len(cached[1]) != len(data.test):
            cached = self._test[data.fold] = (state, rocket_features(model, data.test))
        x = cached[1] * model.scale.numpy()
        with torch.no_grad():
            logits = model.head(torch.as_tensor(x)) / model.temperature
        return torch.softmax(logits, 1).numpy()


def _same(a: dict, b: dict) -> bool:
    """Two transforms' buffers are equal (the test features of one serve the other)."""
    return a.keys() == b.keys() and all(bool((a[k] == b[k]).all()) for k in b)
