"""The relation between drift and accuracy a fit keeps, and the accuracy a file is expected to score from it."""

from __future__ import annotations

import numpy as np

from training import accuracy_by_drift, expected_accuracy
from training.figures import MIN_ROWS


def held_out_rows(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Rows whose chance of being right falls from 95 % at drift 0 to 35 % at drift 2."""
    rng = np.random.default_rng(seed)
    drift = rng.gamma(2.0, 0.3, n)
    right = rng.random(n) < np.clip(0.95 - 0.3 * drift, 0.35, 0.95)
    return drift, right


def test_the_relation_falls_with_drift_and_reads_a_file_by_its_steps() -> None:
    drift, right = held_out_rows(5000)
    relation = accuracy_by_drift(drift, right)
    assert relation is not None and relation["rows"] == 5000
    knots, acc = np.asarray(relation["drift"]), np.asarray(relation["accuracy"])
    assert (np.diff(knots) > 0).all() and (np.diff(acc) <= 1e-12).all()
    assert 2 < len(knots) <= 32
    # a file like the held-out rows expects their accuracy; a file far out, much less; the same drift, the same
    assert abs(expected_accuracy(relation, drift) - right.mean()) < 0.02
    near, far = expected_accuracy(relation, np.full(100, 0.1)), expected_accuracy(relation, np.full(100, 1.8))
    assert near > 0.88 and far < 0.5
    assert np.isclose(expected_accuracy(relation, np.r_[np.full(50, 0.1), np.full(50, 1.8)]), (near + far) / 2)


def test_too_few_rows_or_no_drift_give_no_relation_or_expectation() -> None:
    drift, right = held_out_rows(MIN_ROWS - 1)
    assert accuracy_by_drift(drift, right) is None
    relation = accuracy_by_drift(*held_out_rows(MIN_ROWS))
    assert relation is not None
    assert expected_accuracy(None, np.ones(10)) is None
    assert expected_accuracy(relation, np.full(5, np.nan)) is None
