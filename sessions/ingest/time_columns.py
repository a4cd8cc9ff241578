"""Finding a CSV's time column when nobody named it: a column that increases at every row in steady steps.

The unit is judged by magnitude. A first value that reads as a date between 2001 and 2103 in seconds,
milliseconds, microseconds or nanoseconds since 1970 is an epoch time in that unit; otherwise the column must hold
seconds (from zero or any offset) at a rate a sensor log has. A column of whole numbers that is no epoch time is not
taken: it is a row counter or a unit we cannot judge (milliseconds from zero look like seconds at 0.1 Hz).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

EPOCH_RANGE_S = (1.0e9, 4.2e9)  # 2001-09-09 to 2103-02-04
UNIT_SCALE = (("s", 1.0), ("ms", 1e-3), ("us", 1e-6), ("ns", 1e-9))
RATE_RANGE_HZ = (0.1, 100_000.0)  # what a sensor log's rows can be
STEADY_SHARE = 0.9  # of steps within a factor of two of the median step
PROBE_ROWS = 2000  # rows of each column checked first: a whole column is parsed only when they pass


@dataclass(frozen=True)
class TimeColumn:
    """A column found to hold time.

    Attributes:
        index: Its 0-based position.
        name: Its name (a headerless file's are its positions as text).
        unit: ``"s"``, ``"ms"``, ``"us"`` or ``"ns"``.
        epoch: Whether it counts from 1970 (else seconds from any origin).
        rate_hz: Rows per second at its median step.
    """

    index: int
    name: str
    unit: str
    epoch: bool
    rate_hz: float

    def describe(self) -> str:
        """``column 2 'stamp' (epoch milliseconds, 50 Hz)``."""
        what = f"epoch {dict(UNIT_WORDS)[self.unit]}" if self.epoch else "seconds"
        return f"column {self.index} {self.name!r} ({what}, {self.rate_hz:.4g} Hz)"


UNIT_WORDS = (("s", "seconds"), ("ms", "milliseconds"), ("us", "microseconds"), ("ns", "nanoseconds"))


def judge_unit(first: float) -> str | None:
    """The unit in which ``first`` is an epoch time, or ``None`` when it is none."""
    for unit, scale in UNIT_SCALE:
        if EPOCH_RANGE_S[0] <= first * scale <= EPOCH_RANGE_S[1]:
            return unit
    return None


def as_time(values: np.ndarray) -> tuple[str, bool, float] | None:
    """``(unit, epoch, rate_hz)`` when ``values (N,)`` increase at every row in steady steps, else ``None``."""
    if len(values) < 3 or not np.isfinite(values).all():
        return None
    steps = np.diff(values)
    if not (steps > 0).all():
        return None
    median = float(np.median(steps))
    if np.mean((steps >= 0.5 * median) & (steps <= 2.0 * median)) < STEADY_SHARE:
        return None
    epoch_unit = judge_unit(float(values[0]))
    if epoch_unit is None and np.all(values == np.round(values)):  # a counter, or whole ms from zero: unjudgeable
        return None
    unit = epoch_unit or "s"
    rate = 1.0 / (median * dict(UNIT_SCALE)[unit])
    if not RATE_RANGE_HZ[0] <= rate <= RATE_RANGE_HZ[1]:
        return None
    return unit, epoch_unit is not None, rate


def find_time_columns(head: list[tuple[str, np.ndarray]], whole: Callable[[int], np.ndarray]) -> list[TimeColumn]:
    """The columns that hold time, in file order: each column's first rows ``head`` (name, values ``(n,)``) are
    checked first, and ``whole(index)`` (all its values) only for a column that passed."""
    found = []
    for index, (name, values) in enumerate(head):
        if as_time(values) is None:
            continue
        judged = as_time(whole(index))
        if judged is not None:
            found.append(TimeColumn(index, name, *judged))
    return found
