"""Per run, a member's out-of-fold answers right on its held-out steps (``training.figures.add_run_tally``)."""

from __future__ import annotations

import numpy as np

from training.figures import add_run_tally


def test_each_runs_held_out_steps_are_counted_and_unseen_terrains_left_out() -> None:
    held = [(0, 10, 14, 1), (2, 0, 3, 0), (0, 50, 52, 2)]  # run 0 twice, run 2 once
    true = np.array([1, 1, 1, 1, 0, 0, 0, 2, 2])  # the pieces' steps one after another
    pred = np.array([1, 0, 1, 1, 0, 1, 0, 2, 2])
    tally: dict[int, list[int]] = {}
    add_run_tally(tally, held, true, pred, seen={0, 1})  # terrain 2 never trained on: its steps are not counted
    assert tally == {0: [3, 4], 2: [2, 3]}
    add_run_tally(tally, [(2, 5, 7, 0)], np.array([0, 0]), np.array([0, 0]), seen={0})
    assert tally == {0: [3, 4], 2: [4, 5]}  # a second member adds to the same runs
