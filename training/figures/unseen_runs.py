"""What the model that ships is expected to score on a run it never saw, with an interval over runs.

A session's own accuracy (its runs, with their labels and the votes the labels cast) is not what the robot gets:
the robot gets the bundle, and its next run was in no fold. The folds over logs fit a model without any label or
stretch of the runs they hold out; scored on what the session knows of those runs (the person's labels, and the
terrain the session's scores are sure of over their unlabelled time) they are a run the model never saw, as the
robot's next one is. Runs are the unit: a run's steps are not independent draws (a run that looks like another
terrain is wrong all through), so the interval resamples runs, not steps.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

LEVEL = 0.9  # the interval's confidence: the workbench's figures all say 90 %
FEW_RUNS = 2  # a terrain in this many runs or fewer: the figure runs low (runs_low)
DRAWS = 2000  # bootstrap resamples: the bounds move by well under a point between seeds at this many


@dataclass(frozen=True)
class UnseenRuns:
    """The held-out runs' figure.

    Attributes:
        accuracy: Right time over all the held-out runs' scored time.
        low: The interval's lower bound (``None`` with fewer than two runs: one run says nothing of the spread).
        high: Its upper bound.
        runs: How many runs were scored.
        samples: Scored time, in samples summed over the runs.
        per_run: Per run (the caller's group id): its accuracy.
    """

    accuracy: float
    low: float | None
    high: float | None
    runs: int
    samples: float
    per_run: dict[int, float]

    def as_dict(self) -> dict:
        """JSON-ready, as a version's metrics keep it."""
        return {
            "accuracy": self.accuracy,
            "low": self.low,
            "high": self.high,
            "runs": self.runs,
            "samples": self.samples,
            "per_run": {str(k): v for k, v in self.per_run.items()},
        }


def unseen_runs_figure(
    right: Mapping[int, float], scored: Mapping[int, float], *, level: float = LEVEL, seed: int = 0
) -> UnseenRuns | None:
    """The time-weighted accuracy over held-out runs and a percentile bootstrap interval over runs.

    Args:
        right: Per run, the time its held-out model named right (samples; fractional where a stretch was scored on
            a sample of its rows).
        scored: Per run, the time scored (samples), the same keys.
        level: The interval's confidence.
        seed: The bootstrap's seed (the figure is the same on every call with the same inputs).

    Returns:
        The figure, or ``None`` when no run has scored time.
    """
    keys = [k for k in scored if scored[k] > 0]
    if not keys:
        return None
    r = np.asarray([right.get(k, 0.0) for k in keys], np.float64)  # (R,)
    n = np.asarray([scored[k] for k in keys], np.float64)  # (R,)
    accuracy = float(r.sum() / n.sum())
    low = high = None
    if len(keys) >= 2:
        from scipy.stats import bootstrap  # scipy.stats takes a second to import: only a fit states the figure

        def pooled(rr: np.ndarray, nn: np.ndarray, axis: int = -1) -> np.ndarray:
            return rr.sum(axis=axis) / nn.sum(axis=axis)

        got = bootstrap(
            (r, n),
            pooled,
            paired=True,
            vectorized=True,
            n_resamples=DRAWS,
            confidence_level=level,
            method="percentile",
            rng=np.random.default_rng(seed),
        )
        low, high = float(got.confidence_interval.low), float(got.confidence_interval.high)
    per_run = {k: float(r[j] / n[j]) for j, k in enumerate(keys)}
    return UnseenRuns(accuracy, low, high, len(keys), float(n.sum()), per_run)


def runs_low(got: Mapping | None) -> bool:
    """Whether the figure is known to run low: a measured terrain is in two runs only, so the model that held one
    out learnt that terrain from half of what the model that ships did (BorealTC with one labelled run per terrain:
    18-43 % stated against 64-75 % on runs never in the session, benchmarks/results/loop.md)."""
    return bool(got) and 0 < int(got.get("fewest_runs", 0)) <= FEW_RUNS


def unseen_words(got: Mapping | None) -> str | None:
    """A version's ``unseen_runs`` in a few words: ``"≈ 72 % (90 % interval 61–80 %, 6 runs held out)"``, with a
    caution where it runs low (:func:`runs_low`); ``None`` when it has none (a quick fine-tune, a family without
    folds over runs, one labelled run)."""
    if not got or got.get("accuracy") is None:
        return None
    runs = int(got.get("runs", 0))
    if got.get("low") is None:
        words = f"≈ {100 * got['accuracy']:.0f} % ({runs} run held out: no interval)"
    else:
        words = (
            f"≈ {100 * got['accuracy']:.0f} % (90 % interval {100 * got['low']:.0f}–{100 * got['high']:.0f} %, "
            f"{runs} runs held out)"
        )
    if runs_low(got):
        words += (
            f"; a terrain is in {int(got['fewest_runs'])} runs only, so the run held out took half of it away: "
            "expect more of the model that ships, which learnt from both"
        )
    return words


def unseen_fell(before: Mapping | None, after: Mapping | None) -> str | None:
    """One line when a new version's figure for runs it never saw lies below the interval of the version before it
    (labelling more made the model that ships worse, as far as the session can tell); ``None`` otherwise."""
    if not before or not after or before.get("low") is None or after.get("accuracy") is None:
        return None
    if after["accuracy"] >= before["low"]:
        return None
    return (
        f"the model that ships fell on runs it never saw: ≈ {100 * after['accuracy']:.0f} %, below the last "
        f"version's interval ({100 * before['low']:.0f}–{100 * before['high']:.0f} %)"
    )
