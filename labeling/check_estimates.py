"""What the person's checks say of the model: right on X of N, with a Wilson interval.

A check (``sessions.Check``) is the model's answer on a piece before the person's label there trained it. Spot checks
are drawn uniformly from the unlabelled time, so the share right of them is an unbiased estimate of the accuracy
there; checks of ranked suggestions are drawn where the model is unsure, drifted or unchecked, so theirs says how the
model does where it is doubted, and runs low. Arrays in, numbers out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

Z95 = 1.959964  # the normal quantile of a two-sided 95 % interval


def wilson(right: int, n: int, *, z: float = Z95) -> tuple[float, float]:
    """The Wilson score interval of ``right`` successes in ``n`` trials (``(0, 1)`` when ``n`` is 0): unlike the
    normal approximation it stays inside [0, 1] and is honest for a handful of checks, as a person makes."""
    if n <= 0:
        return 0.0, 1.0
    p = right / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


@dataclass(frozen=True)
class CheckEstimate:
    """Right on ``right`` of ``n`` checks, and the 95 % Wilson interval of the share."""

    right: int
    n: int
    low: float
    high: float

    @property
    def accuracy(self) -> float:
        return self.right / self.n if self.n else float("nan")

    def words(self, what: str = "checks") -> str:
        """``"right on 9 of 12 checks (75 %, 95 % interval 47–91 %)"``."""
        return (
            f"right on {self.right} of {self.n} {what} ({100 * self.accuracy:.0f} %, 95 % interval "
            f"{100 * self.low:.0f}–{100 * self.high:.0f} %)"
        )


def check_estimate(right: Sequence[bool]) -> CheckEstimate | None:
    """The estimate of a set of checks (``True``: the model named the person's terrain); ``None`` without any."""
    n = len(right)
    if n == 0:
        return None
    x = int(sum(bool(r) for r in right))
    return CheckEstimate(x, n, *wilson(x, n))
