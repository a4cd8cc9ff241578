"""The model's predicted stretches: smoothed, short flickers merged, confidence per stretch."""

from __future__ import annotations

import itertools

import numpy as np

from labeling import predicted_stretches, uncovered


def _probs(labels: list[int], k: int = 3, sure: float = 0.8) -> np.ndarray:
    p = np.full((len(labels), k), (1 - sure) / (k - 1))
    p[np.arange(len(labels)), labels] = sure
    return p


def test_flicker_is_merged_and_stretches_cover_the_log() -> None:
    labels = [0] * 100 + [1] * 3 + [0] * 50 + [2] * 120  # a 3-step flicker inside terrain 0
    out = predicted_stretches(_probs(labels), window=1, min_len=20)
    assert [(s.start, s.stop, s.terrain) for s in out] == [(0, 153, 0), (153, 273, 2)]
    assert all(0.0 < s.confidence <= 1.0 for s in out)
    assert out[0].confidence < 0.8  # the flicker's steps lower its mean


def test_smoothing_and_confidence() -> None:
    rng = np.random.default_rng(0)
    labels = [0] * 200 + [1] * 200
    noisy = np.where(rng.random(400) < 0.2, 2, labels)  # one step in five wrong
    out = predicted_stretches(_probs(list(noisy)), window=25, min_len=10)
    assert [s.terrain for s in out] == [0, 1]
    assert abs(out[0].stop - 200) <= 5
    unsure = predicted_stretches(_probs(labels, sure=0.5), window=1, min_len=1)
    sure = predicted_stretches(_probs(labels, sure=0.95), window=1, min_len=1)
    assert unsure[0].confidence < sure[0].confidence


def test_edge_cases() -> None:
    assert predicted_stretches(np.zeros((0, 3)), window=5, min_len=5) == []
    (one,) = predicted_stretches(_probs([1] * 7), window=5, min_len=50)  # shorter than min_len, alone: kept
    assert (one.start, one.stop, one.terrain) == (0, 7, 1)


def test_an_hour_of_flicker_is_merged_in_one_pass() -> None:
    """Runs are merged shortest first through a heap: an hour at 100 Hz of pure flicker is thousands of runs."""
    rng = np.random.default_rng(1)
    probs = rng.random((360_000, 6))
    out = predicted_stretches(probs, window=100, min_len=100)
    assert out[0].start == 0 and out[-1].stop == len(probs)
    assert all(a.stop == b.start and a.terrain != b.terrain for a, b in itertools.pairwise(out))
    assert min(s.stop - s.start for s in out) >= 100


def test_uncovered_leaves_labelled_time_alone() -> None:
    assert uncovered(0, 100, []) == [(0, 100)]
    assert uncovered(0, 100, [(10, 20), (15, 30), (90, 120)]) == [(0, 10), (30, 90)]
    assert uncovered(0, 100, [(-5, 200)]) == []
    assert uncovered(0, 100, [(3, 97)], min_len=5) == []  # slivers left between labels are not labels
    assert uncovered(50, 60, [(0, 10), (70, 80)]) == [(50, 60)]
