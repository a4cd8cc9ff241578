"""Classification metrics, computed with scikit-learn."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def classification_metrics(y_true: np.ndarray, y_pred: np.ndarray, classes: Sequence[str]) -> dict:
    """Accuracy, macro-F1 (over the classes present in ``y_true``), per-class recall and the confusion matrix
    (NaN figures when ``y_true`` is empty).

    Args:
        y_true: ``(N,)`` class indices.
        y_pred: ``(N,)`` class indices.
        classes: Names of all ``K`` classes.
    """
    labels = list(range(len(classes)))
    if len(y_true) == 0:  # nothing could be measured (each terrain's only piece in its own fold): no figure
        nan = float("nan")
        empty = [[0] * len(labels) for _ in labels]
        return {
            "accuracy": nan,
            "macro_f1": nan,
            "per_class_recall": {},
            "confusion": empty,
            "classes": list(classes),
            "n": 0,
        }
    # imported where used: scikit-learn and SciPy add 2 s to every CLI start, and classify, export and serve never fit
    from sklearn.metrics import accuracy_score, confusion_matrix, f1_score, recall_score

    present = sorted(set(np.asarray(y_true).tolist()))
    recall = recall_score(y_true, y_pred, labels=labels, average=None, zero_division=0)
    return {
        "accuracy": float(accuracy_score(y_true, y_pred)),
        "macro_f1": float(f1_score(y_true, y_pred, labels=present, average="macro", zero_division=0)),
        "per_class_recall": {c: float(r) for c, r, k in zip(classes, recall, labels, strict=True) if k in present},
        "confusion": confusion_matrix(y_true, y_pred, labels=labels).tolist(),
        "classes": list(classes),
        "n": len(y_true),
    }


def expected_calibration_error(probs: np.ndarray, y_true: np.ndarray, *, bins: int = 15) -> float:
    """How far confidence is from accuracy: the mean over equal-width confidence bins of ``|accuracy − confidence|``,
    weighted by the bin's share of samples (Guo et al., 2017). ``probs (N, K)``, ``y_true (N,)``; 0 is calibrated."""
    confidence = probs.max(axis=1)
    hit = probs.argmax(axis=1) == y_true
    which = np.minimum((confidence * bins).astype(int), bins - 1)
    total = 0.0
    for b in range(bins):
        members = which == b
        if members.any():
            total += members.mean() * abs(hit[members].mean() - confidence[members].mean())
    return float(total)
