"""The status line's figures: the session's from the checks of this version, the shipped model's on a new run, and
the fit's on the labelled pieces in grey, the terrains it misses there on hover."""

from __future__ import annotations

import numpy as np

from training import terrain_estimate
from workbench.ui.status_bar import figure_html

CLASSES = ("concrete", "grass", "sand")


def _steps(recalls: tuple[float, ...], n: int = 100) -> tuple[np.ndarray, np.ndarray]:
    true = np.repeat(np.arange(len(recalls)), n)
    pred = np.concatenate(
        [np.r_[np.full(round(r * n), k), np.full(n - round(r * n), (k + 1) % 3)] for k, r in enumerate(recalls)]
    )
    return true, pred


def test_the_fits_figure_on_the_labelled_pieces_is_grey_and_names_what_it_misses_on_hover() -> None:
    held = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 2}, _steps((0.9, 0.9, 0.9)), _steps((0.95, 0.9, 0.2)))
    line = figure_html({"estimate": held})
    assert "labelled pieces: " in line and "on held-out logs" in line and "color:#666" in line
    assert "on those pieces it misses sand (20 % recall)" in line  # on hover: a loop drives these pieces' recall down
    assert "#c62828" not in line  # never the session's headline in red
    same = terrain_estimate(CLASSES, {0: 1, 1: 1, 2: 1}, _steps((0.9, 0.4, 0.9)))  # same-run figures miss too
    line = figure_html({"estimate": same})
    assert "new runs may score lower" in line and "misses grass (40 % recall)" in line


def test_no_terrain_is_named_when_every_recall_is_half_or_more() -> None:
    fine = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 2}, _steps((0.9, 0.9, 0.9)), _steps((0.9, 0.5, 0.6)))
    assert "misses" not in figure_html({"estimate": fine})


def test_the_model_that_ships_is_named_apart_from_the_estimate_with_its_interval() -> None:
    held = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 2}, _steps((0.9, 0.9, 0.9)), _steps((0.9, 0.9, 0.9)))
    unseen = {"accuracy": 0.72, "low": 0.612, "high": 0.8, "runs": 6, "samples": 1e5, "per_run": {}}
    line = figure_html({"estimate": held, "unseen_runs": unseen})
    assert "on held-out logs" in line and "shipped, on a new run: ≈ 72 % (61–80 %)</span>" in line
    assert "6 runs held out" in line  # the whole figure on hover
    assert "shipped" not in figure_html({"estimate": held})  # a quick fine-tune states none
    one = figure_html({"estimate": held, "unseen_runs": {**unseen, "low": None, "high": None, "runs": 1}})
    assert "shipped, on a new run: ≈ 72 %</span>" in one and "no interval" in one


def test_once_a_taught_version_is_kept_the_line_states_its_figure_and_names_it() -> None:
    """The export ships the taught version: the status line's "shipped" figure is that version's, named so."""
    from sessions import ModelVersion

    held = terrain_estimate(CLASSES, {0: 2, 1: 2, 2: 2}, _steps((0.9, 0.9, 0.9)), _steps((0.9, 0.9, 0.9)))
    mine = {"accuracy": 0.62, "low": 0.5, "high": 0.7, "runs": 6, "samples": 1e5, "per_run": {}}
    theirs = {**mine, "accuracy": 0.84, "low": 0.79, "high": 0.89}
    taught = ModelVersion(12, "classifier", "models/v0012", "", {"taught_from": 11}, {"unseen_runs": theirs}, False)
    line = figure_html({"estimate": held, "unseen_runs": mine}, taught=taught)
    assert "shipped (taught v12), on a new run: ≈ 84 % (79–89 %)</span>" in line and "≈ 62 %" not in line
    assert "on held-out logs" in line  # the active fit's own figure on the labelled pieces stays
