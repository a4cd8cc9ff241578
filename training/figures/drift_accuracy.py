"""What a new file is expected to score, from its drift: the relation between drift and accuracy a fit measured on
its held-out folds (``benchmarks/studies/expected_borealtc.py``).

A fit's ensemble members each held out blocks of the labelled time; each held-out row has the member's drift (how
unlike the member's own labelled rows it is, :mod:`.spectral_cnn.window_drift`) and whether the member was right.
:func:`accuracy_by_drift` bins those pairs by drift and fits accuracy as a falling function of it over the bins
(isotonic regression: monotone, no shape assumed). :func:`expected_accuracy` is the relation's mean over a
file's steps.

Chosen on BorealTC's inner folds by run (outer fold 1's 55 training runs, 5 inner folds, 10 % labelled; the outer
test runs unread; ``benchmarks/studies/expected_borealtc.py --inner 1``), against what each held-out run scored: the
relation was within 10 points on 40 % of runs (mean error +0.5 points, mean absolute 18.8); the card's figure for
every run 15 % (27.5), the relation capped at the card 18 % (25.6), the mean top probability 31 % (21.1). Runs
score either near the same-run level or far under it, so one figure for all of them is rarely near any. On the
test folds, once per seed: within 10 points on 46 % and 43 % of held-out runs (the issue's target: 80 %).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

KNOTS = 32  # most bins of held-out rows the relation is kept at: a few hundred bytes of JSON in the bundle
BIN_ROWS = 40  # fewest held-out rows in a bin
# fewer held-out rows than this: no relation. Its level is the blocks' accuracy, noise on a few rows: two one-minute
# demo walks, 15 % labelled, held out 90 rows that scored 29 % against 63 % on held-out logs, and a training walk
# that scored 76 % was expected to score 35 %. BorealTC at 10 % of labels holds out over a thousand.
MIN_ROWS = 10 * BIN_ROWS


def accuracy_by_drift(drift: np.ndarray, correct: np.ndarray) -> dict | None:
    """The relation, from held-out rows' drift ``(N,)`` and whether each was predicted right ``(N,)``.

    Returns:
        ``{"drift": [...], "accuracy": [...], "rows": N}``: knots (drift ascending, accuracy not rising; each a
        bin of the rows in drift order: its mean drift, and the isotonic fit over the bins' accuracies), read
        between them by linear interpolation and past the ends as the end knots; ``None`` with fewer than
        ``MIN_ROWS`` rows.
    """
    drift = np.asarray(drift, np.float64)
    correct = np.asarray(correct, np.float64)
    keep = np.isfinite(drift)
    drift, correct = drift[keep], correct[keep]
    if len(drift) < MIN_ROWS:
        return None
    # the rows in drift order, cut into bins of BIN_ROWS or more: a knot is a bin's mean, so the ends of the
    # relation rest on a bin each, not on the few rows farthest out (on two one-minute demo walks the last rows'
    # errors put the relation at 0 % past drift 1)
    order = np.argsort(drift, kind="stable")
    bins = np.array_split(order, max(1, min(KNOTS, len(drift) // BIN_ROWS)))
    centre = np.asarray([drift[b].mean() for b in bins])
    share = np.asarray([correct[b].mean() for b in bins])
    size = np.asarray([len(b) for b in bins], np.float64)
    # imported where used: scikit-learn and SciPy add 2 s to every CLI start, and classify, export and serve never fit
    from sklearn.isotonic import IsotonicRegression

    fit = IsotonicRegression(increasing=False, y_min=0.0, y_max=1.0).fit(centre, share, sample_weight=size)
    values = fit.predict(centre)
    return {
        "drift": [float(x) for x in centre],
        "accuracy": [float(y) for y in values],
        "rows": len(drift),
    }


def expected_accuracy(relation: Mapping | None, drift: np.ndarray) -> float | None:
    """The accuracy a file is expected to score: the relation's mean over its steps' drift ``(T,)``; ``None``
    without a relation or any finite drift."""
    if not relation or drift is None:
        return None
    drift = np.asarray(drift, np.float64)
    drift = drift[np.isfinite(drift)]
    if len(drift) == 0:
        return None
    return float(np.interp(drift, np.asarray(relation["drift"]), np.asarray(relation["accuracy"])).mean())
