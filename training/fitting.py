"""What every family's stage-2 fit shares: the segments it reads, the folds over them, the result it returns, and
configs as JSON."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from torch import nn

Segment = tuple[int, int, int, int]  # (log index, start, stop, class index)


@dataclass
class ClassifierFit:
    """The fold models (the ensemble), out-of-fold metrics and per-fold training curves."""

    models: list[nn.Module]
    metrics: dict
    history: list[list[dict[str, float]]] = field(default_factory=list)
    folds: list[list[int]] = field(default_factory=list)  # validation indices of each fold: pieces, else segments
    pieces: list[tuple[int, int, int]] = field(default_factory=list)  # (segment index, start, stop) per piece
    drift: object | None = None  # the family's drift reference (the default family's ``DriftReference``), if any


def fold_indices(labels: Sequence[int], k: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """k folds over segments, stratified by terrain where every class has enough segments.

    Each segment is wholly in one fold. With fewer than two segments there is one "fold" training on everything.
    """
    # imported where used: scikit-learn and SciPy add 2 s to every CLI start, and classify, export and serve never fit
    from sklearn.model_selection import KFold, StratifiedKFold

    n = len(labels)
    idx = np.arange(n)
    if n < 2:
        return [(idx, idx)]
    k = min(k, n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # "least populated class has only N members"
        try:
            return list(StratifiedKFold(k, shuffle=True, random_state=seed).split(idx, labels))
        except ValueError:
            return list(KFold(k, shuffle=True, random_state=seed).split(idx))


def to_dict(config: object) -> dict:
    """A config as plain JSON-able data."""
    return asdict(config)  # type: ignore[arg-type]
