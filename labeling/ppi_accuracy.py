"""Accuracy as an interval: uniform checks of the model it judges, corrected by the model's own confidence.

A uniform check (a spot check: a piece drawn at random from the time nobody labelled, answered by the person) is an
unbiased test of the model that was active when it was made. Prediction-powered inference (Angelopoulos et al., Science
2023) adds what the model says of all that time: the mean of its confidence there, corrected by how far confidence and
rightness differed on the checks, which keeps the estimate unbiased however the confidence is calibrated. PPI++'s power
tuning (Angelopoulos, Duchi & Zrnic, 2023) weights the confidence by how well it tracked rightness on the checks: ``lam
= 0`` is the checks alone, and a confidence that says nothing costs nothing.

The interval is Wilson's score interval at the estimate with the checks' effective number (their count times the
variance the confidence took away, at most ``MAX_GAIN`` times, which is 1: the count itself, see its comment): for a
handful of checks a normal interval around a share of 8 right of 8 has no width at all. Written here (about 40 lines)
rather than taken from ``ppi-python``, whose install pulls numba, statsmodels and a downloader for one mean.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

Z90 = 1.6448536269514722  # the two-sided 90 % normal quantile: the workbench's intervals all say 90 %
# the most the confidence may multiply the checks' count by. 1: the interval is Wilson's at the estimate with the
# checks' own count. With 24 checks the variance the confidence seems to take away is itself a noisy estimate: on
# simulated sessions a cap of 4 held coverage at 0.87-0.97, but over the loop's stand-ins (demo walks seeds 1-3,
# BorealTC new runs seeds 1-2, 25 session figures after the rounds) the narrowed intervals covered the truth 20 times,
# 21.5 points wide, where Wilson's at the same estimate with the checks' count covered it 24 times, 23.7 wide (the
# checks alone: 23, 23.8). The estimate keeps the confidence's correction; the width does not count on it
# (benchmarks/results/estimates.md)
MAX_GAIN = 1.0


@dataclass(frozen=True)
class PoweredAccuracy:
    """An accuracy and its interval.

    Attributes:
        accuracy: The estimate, in [0, 1].
        low: The interval's lower bound.
        high: Its upper bound.
        checks: How many checks it rests on.
        lam: The confidence's weight (0: the checks alone).
        effective: The checks' effective number (``checks`` when ``lam`` is 0).
    """

    accuracy: float
    low: float
    high: float
    checks: int
    lam: float
    effective: float

    def words(self) -> str:
        """``"≈ 94 % (90 % interval 88–97 %, from 12 checks)"``."""
        return (
            f"≈ {100 * self.accuracy:.0f} % (90 % interval {100 * self.low:.0f}–{100 * self.high:.0f} %, from "
            f"{self.checks} check{'s' if self.checks != 1 else ''})"
        )


@dataclass(frozen=True)
class Moments:
    """The mean, variance and count of the model's confidence over a stretch of time: all the estimate needs of it,
    so a fleet's hours are summed log by log, never held together.

    Attributes:
        mean: The mean.
        var: The variance (over ``n``, not ``n - 1``).
        n: How many steps.
    """

    mean: float
    var: float
    n: int

    @staticmethod
    def of(values: np.ndarray) -> Moments:
        """The moments of ``(N,)`` values."""
        v = np.asarray(values, np.float64)
        return Moments(float(v.mean()), float(v.var()), len(v)) if len(v) else Moments(0.0, 0.0, 0)

    @staticmethod
    def pooled(parts: Sequence[Moments]) -> Moments:
        """The moments of the parts' values taken together."""
        n = sum(p.n for p in parts)
        if n == 0:
            return Moments(0.0, 0.0, 0)
        mean = sum(p.mean * p.n for p in parts) / n
        second = sum((p.var + p.mean * p.mean) * p.n for p in parts) / n
        return Moments(mean, max(0.0, second - mean * mean), n)


def wilson_bounds(p: float, n: float, z: float = Z90) -> tuple[float, float]:
    """Wilson's score interval of a share ``p`` over ``n`` (possibly effective, not whole) trials."""
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    # at a share of 0 or 1 the bound is that share exactly (in floating point centre + half falls short of 1)
    return (0.0 if p <= 0 else max(0.0, centre - half)), (1.0 if p >= 1 else min(1.0, centre + half))


def powered_accuracy(
    right: np.ndarray,
    sure_checked: np.ndarray,
    sure_all: np.ndarray | Moments,
    *,
    z: float = Z90,
    max_gain: float = MAX_GAIN,
) -> PoweredAccuracy | None:
    """The share of the time nobody labelled that the model names right, from uniform checks and its confidence.

    Args:
        right: ``(n,)`` 1 where the model named the person's terrain at a uniform check, 0 where not.
        sure_checked: ``(n,)`` the model's confidence at those checks (its probability of the terrain it named).
        sure_all: ``(N,)`` the same over the time nobody labelled (the checks' time may be among it), or its
            ``Moments``.
        z: The normal quantile of the interval (90 %: ``Z90``).
        max_gain: The most the confidence may multiply the checks' count by (``MAX_GAIN``).

    Returns:
        The estimate, or ``None`` without checks.
    """
    y = np.asarray(right, np.float64)  # (n,)
    f = np.asarray(sure_checked, np.float64)  # (n,)
    g = sure_all if isinstance(sure_all, Moments) else Moments.of(sure_all)  # of the (N,) confidences
    n, big = len(y), g.n
    if n == 0:
        return None
    lam, effective = 0.0, float(n)
    if n >= 2 and big > 0 and f.var() > 0 and y.var() > 0:
        # PPI++: the weight that minimises the estimate's variance, clipped to [0, 1] (at 1: plain PPI)
        lam = float(np.clip(np.cov(y, f)[0, 1] / ((1 + n / big) * f.var(ddof=1)), 0.0, 1.0))
        rest = (y - lam * f).var(ddof=1) / n + lam * lam * g.var / big  # the estimate's variance
        effective = float(min(y.var(ddof=1) / max(rest, 1e-12), max_gain * n))
        effective = max(effective, float(n))  # clipped lam never adds variance over the checks alone
    estimate = float(y.mean() + lam * (g.mean - f.mean())) if big else float(y.mean())
    estimate = min(1.0, max(0.0, estimate))
    low, high = wilson_bounds(estimate, effective, z)
    return PoweredAccuracy(estimate, low, high, n, lam, effective)
