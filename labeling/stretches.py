"""The model's predicted stretches: what a person reviews and accepts instead of labelling from scratch.

Per-step probabilities flicker between terrains at a frame's scale; a person judges stretches. The probabilities
are smoothed over a short centred window, the argmax is cut into runs of one terrain, runs shorter than ``min_len``
are merged into a neighbour, and each stretch carries its mean confidence (the smoothed probability of its terrain)
for the UI's opacity. Arrays in, arrays out.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
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
    cum = np.concatenate([np.zeros((1, k)), np.cumsum(p, axis=0)])  # (T + 1, K): a run's mean in O(1)
    label = p.argmax(axis=1)  # (T,)
    edges = np.flatnonzero(np.diff(label)) + 1
    starts = np.r_[0, edges].tolist()
    stops = np.r_[edges, n].tolist()
    terrain = label[starts].tolist()
    r = len(starts)
    before, after = list(range(-1, r - 1)), [*range(1, r), -1]  # neighbours, as a linked list
    alive = [True] * r

    def mean(i: int, a: int, b: int) -> float:  # run i's terrain's smoothed probability over [a, b)
        return float(cum[b, terrain[i]] - cum[a, terrain[i]]) / (b - a)

    # Shortest run first (the earliest among equals), each merged into the neighbour it is more like: a heap with
    # stale entries skipped, since runs only grow. An hour of flicker has thousands of runs.
    heap = [(stops[i] - starts[i], i) for i in range(r)]
    heapq.heapify(heap)
    while heap:
        length, i = heapq.heappop(heap)
        if not alive[i] or length != stops[i] - starts[i]:
            continue
        if length >= min_len:
            break
        left, right = before[i], after[i]
        if left < 0 and right < 0:
            break
        a, b = starts[i], stops[i]
        into = max((j for j in (left, right) if j >= 0), key=lambda j: mean(j, a, b))
        starts[into], stops[into] = min(starts[into], a), max(stops[into], b)
        alive[i] = False
        if left >= 0:
            after[left] = right
        if right >= 0:
            before[right] = left
        if left >= 0 and right >= 0 and terrain[left] == terrain[right]:  # neighbours of one terrain become one
            stops[left] = stops[right]
            alive[right] = False
            after[left] = after[right]
            if after[right] >= 0:
                before[after[right]] = left
            into = left
        heapq.heappush(heap, (stops[into] - starts[into], into))
    out = []
    i = next(j for j in range(r) if alive[j] and before[j] < 0)
    while i >= 0:
        a, b = starts[i], stops[i]
        out.append(PredictedStretch(a, b, terrain[i], mean(i, a, b)))
        i = after[i]
    return out


def uncovered(start: int, stop: int, covered: Sequence[tuple[int, int]], *, min_len: int = 1) -> list[tuple[int, int]]:
    """The parts of ``[start, stop)`` outside every ``[a, b)`` of ``covered``, each at least ``min_len`` long: what
    accepting a stretch labels without touching a label a person already made."""
    pieces, at = [], start
    for a, b in sorted((max(a, start), min(b, stop)) for a, b in covered if b > start and a < stop):
        if a - at >= min_len:
            pieces.append((at, a))
        at = max(at, b)
    if stop - at >= min_len:
        pieces.append((at, stop))
    return pieces
