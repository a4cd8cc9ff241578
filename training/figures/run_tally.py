"""Per run, how often out-of-fold predictions named the labelled terrain: the model's own evidence on each run.

A blocked fold's member never trained on its held-out block, so its answers there are a test of the ensemble on
that run's labelled time, made with the rest of the run's labels in hand (what the model knows of the run). The
workbench weighs a run's own labels against the model by it (``labeling.blend_votes``'s trust): where the model
fitted on a run's labels still misses its held-out pieces, the run's vote decides; where it names them, it keeps
its answer.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence

import numpy as np


def add_run_tally(
    tally: dict[int, list[int]],
    held: Sequence[tuple[int, int, int, int]],
    true: np.ndarray,
    pred: np.ndarray,
    seen: Collection[int],
) -> None:
    """Add to ``tally`` (per run index, ``[right, steps]``) a member's held-out pieces.

    Args:
        tally: Updated in place.
        held: The pieces ``(run, start, stop, class)`` held out, in the order of ``true`` and ``pred``.
        true: ``(T,)`` each held-out step's labelled class, the pieces' steps one after another.
        pred: ``(T,)`` the member's class at each.
        seen: The classes the member trained on: a step of another cannot be right and is not counted.
    """
    runs = np.repeat(np.asarray([p[0] for p in held], np.int64), [p[2] - p[1] for p in held])  # (T,)
    keep = np.isin(true, list(seen))
    right = np.bincount(runs[keep], weights=(true == pred)[keep].astype(np.float64))
    steps = np.bincount(runs[keep])
    for g in np.flatnonzero(steps):
        now = tally.setdefault(int(g), [0, 0])
        now[0] += int(right[g])
        now[1] += int(steps[g])
