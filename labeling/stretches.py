"""The model's predicted stretches: what a person reviews and accepts instead of labelling from scratch.

Per-step probabilities flicker between terrains at a frame's scale; a person judges stretches. The probabilities
are smoothed over a short centred window, the argmax is cut into runs of one terrain, runs shorter than ``min_len``
are merged into a neighbour, and each stretch carries its mean confidence (the smoothed probability of its terrain)
for the UI's opacity. Arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .tracks import smooth


@dataclass(frozen=True)
class PredictedStretch:
    """A run of one predicted terrain: samples ``[start, stop)``, the class index and its mean smoothed probability."""

    start: int
    stop: int
    terrain: int
    confidence: float


def predicted_stretches(probs: np.ndarray, *, window: int, min_len: int) -> list[PredictedStretch]:
    """The model's stretches of one log.

    Args:
        probs: ``(T, K)`` per-step class probabilities.
        window: Samples of the centred moving average applied to each class's probability first.
        min_len: Shortest stretch kept on its own; a shorter run joins the neighbour it is more like (by the smoothed
            probability of that neighbour's terrain over the run).

    Returns:
        Stretches covering ``[0, T)`` in order, neighbours of different terrains.
    """
    probs = np.asarray(probs, np.float64)
    n, k = probs.shape
    if n == 0:
        return []
    p = np.stack([smooth(probs[:, j], window) for j in range(k)], axis=1)  # (T, K)
    label = p.argmax(axis=1)  # (T,)
    edges = np.flatnonzero(np.diff(label)) + 1
    runs = [[int(a), int(b), int(label[a])] for a, b in zip(np.r_[0, edges], np.r_[edges, n], strict=True)]
    while len(runs) > 1:
        short = min(range(len(runs)), key=lambda i: runs[i][1] - runs[i][0])
        a, b, _ = runs[short]
        if b - a >= min_len:
            break
        left = runs[short - 1] if short > 0 else None
        right = runs[short + 1] if short + 1 < len(runs) else None
        score = {id(r): p[a:b, r[2]].mean() for r in (left, right) if r is not None}
        into = max((r for r in (left, right) if r is not None), key=lambda r: score[id(r)])
        into[0], into[1] = min(into[0], a), max(into[1], b)
        del runs[short]
        merged = []  # neighbours that now share a terrain become one
        for r in runs:
            if merged and merged[-1][2] == r[2]:
                merged[-1][1] = r[1]
            else:
                merged.append(r)
        runs = merged
    return [PredictedStretch(a, b, c, float(p[a:b, c].mean())) for a, b, c in runs]
