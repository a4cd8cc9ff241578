"""The default family as the label-efficiency simulation's learner: every round fits the window classifier afresh on
every label so far, with self-training on the pool's unlabelled stretches, as the UI's Retrain does."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

import labeling
from training import SpectralSteps, WindowFitConfig, classification_metrics, fit_window_classifier, terrain_recalls

from ..cycle import free_stretches, score_logs, stretch_units


class WindowLearner:
    """Labels in; the pool's scores and held-out accuracy out (``labeling.simulate``'s learner).

    Args:
        pool: Per pool log, its per-step spectral summaries.
        pool_error: Per pool log, ``(T,)`` stage-1 surprise (what the highlights and cold-start suggestions read).
        classes: Terrain names.
        fit: The window classifier's settings.
        change_points: Per pool log, its change points (self-training's stretches never cross one); ``None`` for
            pool logs that are one terrain by construction (BorealTC's partitions).
        longest: Longest self-training stretch, in samples.
        test_predict: The fold models' held-out truth and predictions.
    """

    def __init__(
        self,
        pool: list[SpectralSteps],
        pool_error: list[np.ndarray],
        classes: Sequence[str],
        fit: WindowFitConfig,
        *,
        change_points: Sequence[np.ndarray] | None,
        longest: int,
        test_predict: Callable[[list], tuple[np.ndarray, np.ndarray]],
    ) -> None:
        self.pool, self.pool_error, self.classes, self.fit = pool, pool_error, classes, fit
        self.change_points, self.longest, self.test_predict = change_points, longest, test_predict

    def _points(self, i: int) -> np.ndarray:
        return np.zeros(0, np.int64) if self.change_points is None else self.change_points[i]

    def _stretches(self, labels: Sequence[labeling.Labelled]) -> list[tuple[int, int, int]]:
        shortest = self.pool[0].config.span
        out = []
        for i, f in enumerate(self.pool):
            taken = [(a, b) for log, a, b, _ in labels if log == i]
            spans = free_stretches(len(f), self._points(i), taken, longest=self.longest, shortest=shortest)
            out += [(i, a, b) for a, b in spans]
        return out

    def __call__(self, labels: Sequence[labeling.Labelled]) -> labeling.Round:
        if not labels:
            return labeling.Round([labeling.LogScores(e) for e in self.pool_error], float("nan"))
        segments = [(int(log), int(a), int(b), int(c)) for log, a, b, c in labels]
        stretches = self._stretches(labels) if self.fit.self_training else []
        settings = replace(self.fit, held_out=False)  # the simulation measures held-out logs itself
        units = stretch_units(stretches, self._points) if settings.unit_agree else None  # off by default
        fit = fit_window_classifier(
            self.pool, segments, self.classes, config=settings, stretches=stretches, units=units
        )
        scores = score_logs(fit.models, self.pool, self.pool_error, drift=fit.drift, batch=256)  # as the UI scores
        y_true, y_pred = self.test_predict(fit.models)
        m = classification_metrics(y_true, y_pred, self.classes)
        recall = terrain_recalls(fit.metrics.get("estimate"), self.classes)  # what the session's suggestions read
        return labeling.Round(scores, m["accuracy"], m["macro_f1"], recall)
