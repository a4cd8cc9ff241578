"""Blocked folds: labelled time cut into blocks, every terrain in every fold, no model input read by two folds."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from training import blocked_folds, cut_blocks

SPAN = 160  # a step's input: 7 frames of 40 samples every 20
GUARD = SPAN + 20


def _random_segments(rng: np.random.Generator) -> list[tuple[int, int, int, int]]:
    """Non-overlapping labels on 1-4 logs: short ones and whole runs, neighbours touching at times."""
    segments = []
    for log in range(int(rng.integers(1, 5))):
        t = int(rng.integers(0, 500))
        for _ in range(int(rng.integers(1, 6))):
            length = int(rng.choice([50, 300, 900, 4000, 20_000]))
            segments.append((log, t, t + length, int(rng.integers(0, 4))))
            t += length + int(rng.choice([0, 0, 30, 1000]))
    return segments


@pytest.mark.parametrize("seed", range(40))
def test_no_input_window_is_read_by_two_folds_and_the_pieces_are_the_labels(seed: int) -> None:
    rng = np.random.default_rng(seed)
    segments = _random_segments(rng)
    folds = blocked_folds(segments, int(rng.integers(2, 6)), block=4 * GUARD, guard=GUARD)
    # the pieces tile the segments exactly
    for i, (log, a, b, c) in enumerate(segments):
        mine = sorted((p.start, p.stop) for p in folds.pieces if p.segment == i)
        assert mine[0][0] == a and mine[-1][1] == b and all(x[1] == y[0] for x, y in itertools.pairwise(mine))
        assert all(p.log == log and p.label == c for p in folds.pieces if p.segment == i)
    assert sorted(set(folds.fold_of)) == list(range(folds.k))
    for f in range(folds.k):
        held = [folds.pieces[j] for j in folds.held_out(f)]
        for log, s, e, _ in folds.training(f):
            for p in (p for p in held if p.log == log):
                # a training step t reads [t - SPAN + 1, t]; so does a held-out one: the two ranges never meet
                first_train, last_train = s - SPAN + 1, e - 1
                first_held, last_held = p.start - SPAN + 1, p.stop - 1
                assert last_train < first_held or last_held < first_train, (f, (log, s, e), p)


def test_whole_run_labels_one_run_per_terrain_leave_every_fold_every_terrain() -> None:
    runs = [(i, 0, 30_000, i) for i in range(5)]  # five runs, each one terrain, labelled whole (5 min at 100 Hz)
    folds = blocked_folds(runs, 5, block=4 * GUARD, guard=GUARD)
    assert folds.k == 5
    for f in range(folds.k):
        assert {s[3] for s in folds.training(f)} == set(range(5))
        held = [folds.pieces[j] for j in folds.held_out(f)]
        assert {p.label for p in held} == set(range(5))
        for label in range(5):  # a fold holds out one contiguous stretch of each run
            mine = sorted((p.start, p.stop) for p in held if p.label == label)
            assert all(x[1] == y[0] for x, y in itertools.pairwise(mine))


def test_short_segments_stay_whole_and_long_ones_are_cut_evenly() -> None:
    pieces = cut_blocks([(0, 100, 1500, 0), (0, 2000, 10_000, 1)], 720)
    assert [(p.start, p.stop) for p in pieces if p.segment == 0] == [(100, 1500)]  # under two blocks
    lengths = [p.stop - p.start for p in pieces if p.segment == 1]
    assert len(lengths) == 8000 // 720 and max(lengths) - min(lengths) <= 1 and sum(lengths) == 8000


def test_two_terrains_with_one_label_each_go_to_two_folds() -> None:
    folds = blocked_folds([(0, 300, 900, 0), (0, 1200, 1800, 1)], 5, block=720, guard=180)
    assert folds.k == 2 and sorted(folds.fold_of) == [0, 1]
