"""The session's accuracy from uniform checks, narrowed by the model's confidence: coverage and width simulated."""

from __future__ import annotations

import numpy as np
import pytest

from labeling import Z90, powered_accuracy, wilson


def _session(kind: str, rng: np.random.Generator, n_steps: int = 3000) -> tuple[np.ndarray, np.ndarray]:
    """Whether the model is right at each step of the time nobody labelled, and its confidence there."""
    if kind == "sharp":  # the confidence tells right from wrong: 15 % wrong
        c = np.where(rng.random(n_steps) < 0.15, 0.03, 0.99)
        f = np.where(c > 0.5, rng.uniform(0.85, 1, n_steps), rng.uniform(0.2, 0.5, n_steps))
    elif kind == "overconfident":  # about 80 % right, 15 points surer than it is
        c = rng.beta(4, 1, n_steps)
        f = np.clip(c + 0.15, 0, 1)
    else:  # whole stretches wrong with the confidence hardly lower there: what a run read as another terrain does
        wrong = np.repeat(rng.random(n_steps // 200) < 0.3, 200)
        c = np.where(wrong, 0.05, 0.98)
        f = np.clip(np.where(wrong, 0.7, 0.9) + rng.normal(0, 0.05, n_steps), 0, 1)
    return (rng.random(n_steps) < c).astype(float), f


@pytest.mark.parametrize("kind", ["sharp", "overconfident", "stretches"])
@pytest.mark.parametrize("n", [8, 48])
@pytest.mark.parametrize("max_gain", [1.0, 4.0])
def test_the_90_percent_interval_covers_the_truth_at_least_85_percent_of_the_time(
    kind: str, n: int, max_gain: float
) -> None:
    """The workbench's cap (1: Wilson's at the estimate with the checks' count) and a cap that lets the confidence
    narrow the interval (4) both cover on these simulated sessions; only the second narrows it."""
    rng = np.random.default_rng(n)
    covered, width, alone = 0, 0.0, 0.0
    draws = 200
    for _ in range(draws):
        right, sure = _session(kind, rng)
        at = rng.choice(len(right), n, replace=False)  # uniform checks
        got = powered_accuracy(right[at], sure[at], sure, max_gain=max_gain)
        covered += got.low <= right.mean() <= got.high
        width += got.high - got.low
        low, high = wilson(int(right[at].sum()), n, z=Z90)
        alone += high - low
        assert got.effective <= max_gain * n + 1e-9
    assert covered / draws >= 0.85, (kind, n, covered / draws)
    assert width <= alone * 1.02  # the confidence never widens it past the checks alone (beyond rounding)
    if kind == "sharp" and max_gain > 1:  # a confidence that tells right from wrong narrows it by a third or more
        assert width < 0.75 * alone, (width / draws, alone / draws)


def test_checks_all_right_still_have_an_interval_and_a_blind_confidence_changes_nothing() -> None:
    got = powered_accuracy(np.ones(8), np.linspace(0.5, 1, 8), np.full(1000, 0.7))
    assert got is not None and got.lam == 0.0 and got.accuracy == 1.0
    assert (got.low, got.high) == pytest.approx(wilson(8, 8, z=Z90))  # the checks alone: 8 of 8 is not certainty
    rng = np.random.default_rng(1)
    right = (rng.random(24) < 0.8).astype(float)
    blind = powered_accuracy(right, np.full(24, 0.9), rng.uniform(0, 1, 5000))  # the same confidence at every check
    assert blind.lam == 0.0 and blind.accuracy == right.mean() and blind.effective == 24
    assert powered_accuracy(np.zeros(0), np.zeros(0), np.ones(10)) is None


def test_the_estimate_moves_with_the_confidence_over_the_unchecked_time_and_says_so_in_words() -> None:
    right = np.array([1, 1, 1, 0, 1, 1, 0, 1, 1, 1], float)
    sure = np.where(right > 0, 0.95, 0.4)  # sure where right, unsure where wrong
    better = powered_accuracy(right, sure, np.full(1000, 0.95))  # the rest of the time looks like where it was right
    worse = powered_accuracy(right, sure, np.full(1000, 0.4))
    assert better.lam > 0 and better.accuracy > right.mean() > worse.accuracy
    assert better.words().startswith(f"≈ {100 * better.accuracy:.0f} % (90 % interval ")
    assert better.words().endswith("from 10 checks)")
