"""Verification: the fewest uniform checks that bring the session's interval under a width, and where they go.

After a Retrain the person's earlier checks tested an older model. A verification is a fresh, fair sample of the
new one: pieces drawn uniformly from the time nobody labelled, stratified by run in proportion to that time (each
run gets its share, so a run is never left unchecked by chance and the pooled share stays a uniform sample's).
How many: the smallest count whose Wilson interval at the accuracy expected is no wider than asked, fewer where the
model's confidence already narrowed the interval of this version's checks (``powered_accuracy``'s effective number).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from .placed_picks import Span, Suggestion, coverage, spot_checks
from .ppi_accuracy import Z90, wilson_bounds

VERIFY_REASON = "verification: a piece drawn at random from this run's unlabelled time, a fair test of this model"
MOST_CHECKS = 400  # a plan past this is a width the session cannot afford to verify: it is said, not drawn


def proportional(sizes: Sequence[int], k: int) -> list[int]:
    """``k`` draws over strata of ``sizes``, in proportion (largest remainders first; empty strata get none)."""
    total = sum(sizes)
    if total <= 0 or k <= 0:
        return [0] * len(sizes)
    exact = [k * s / total for s in sizes]
    got = [int(e) for e in exact]
    for i in sorted(range(len(sizes)), key=lambda i: exact[i] - got[i], reverse=True)[: k - sum(got)]:
        got[i] += 1
    return got


def checks_needed(accuracy: float, width: float, *, gain: float = 1.0, z: float = Z90) -> int:
    """The fewest uniform checks whose interval is at most ``width`` wide at ``accuracy`` (``MOST_CHECKS + 1``
    when more than ``MOST_CHECKS``).

    Args:
        accuracy: The accuracy expected, in [0, 1] (the estimate so far, else the model's mean confidence).
        width: The interval's width wanted, in [0, 1] (0.10: ten points, ±5).
        gain: How much each check counts (``effective / checks`` of the version's estimate so far; 1: alone).
        z: The interval's normal quantile.
    """
    p = min(max(accuracy, 0.0), 1.0)
    gain = max(gain, 1.0)
    for n in range(1, MOST_CHECKS + 1):
        low, high = wilson_bounds(p, n * gain, z)
        if high - low <= width + 1e-12:
            return n
    return MOST_CHECKS + 1


def verification_checks(
    lengths: Sequence[int],
    labelled: Sequence[Span],
    count: int,
    *,
    max_len: int,
    min_len: int,
    seed: int,
) -> list[Suggestion]:
    """``count`` pieces of up to ``max_len`` around steps drawn uniformly from each log's time nobody labelled, the
    logs' shares in proportion to that time (``proportional``); kind ``"spot check"``, reason ``VERIFY_REASON``.

    Args:
        lengths: Per log, its steps.
        labelled: ``(log, start, stop)`` of the labels.
        count: How many pieces.
        max_len: A piece's longest, in steps.
        min_len: Its shortest (a draw where less is free is drawn again).
        seed: Seed of the draws.

    Returns:
        At most ``count`` pieces: fewer where the time nobody labelled holds fewer (a count past it is not drawn
        for).
    """
    cov = coverage(lengths, labelled)
    free = [len(c) - int(c.sum()) for c in cov]
    out: list[Suggestion] = []
    for log, m in enumerate(proportional(free, count)):
        m = min(m, free[log] // max(min_len, 1))  # no more pieces than the log's free time holds
        if not m:
            continue
        mine = [(0, a, b) for g, a, b in labelled if g == log]
        picks = spot_checks([lengths[log]], mine, [], m, max_len=max_len, min_len=min_len, seed=seed * 7919 + log)
        out += [Suggestion(log, p.start, p.stop, 0.0, VERIFY_REASON, None, 0, "spot check") for p in picks]
    return [Suggestion(p.log, p.start, p.stop, p.score, p.reason, p.guess, i, p.kind) for i, p in enumerate(out)]


def interval_width(accuracy: float, effective: float, *, z: float = Z90) -> float:
    """The Wilson interval's width at ``accuracy`` with ``effective`` checks (1.0 without any)."""
    if effective <= 0 or math.isnan(accuracy):
        return 1.0
    low, high = wilson_bounds(accuracy, effective, z)
    return high - low
