"""Active labelling: highlight tracks, suggestions, segment snapping, label-efficiency simulation.

NumPy in, NumPy out: no torch, no UI, no session (``workbench`` wires it to the model and the store).
"""

from .changepoints import Snap, block_summary, change_points, snap_range, spans
from .simulate import (
    CurvePoint,
    Labelled,
    Learner,
    Round,
    bootstrap_final_ratio,
    mean_curve,
    oracle,
    savings,
    simulate,
    table,
    time_to_reach,
)
from .stretches import PredictedStretch, predicted_stretches, uncovered
from .suggest import STRATEGIES, Strategy, Suggestion, candidates, class_weights, coverage, suggest
from .tracks import (
    KINDS,
    Interval,
    Kind,
    LogScores,
    entropy,
    highlight_intervals,
    intervals,
    margin_uncertainty,
    mutual_information,
    normalised_tracks,
    session_normaliser,
    smooth,
)

__all__ = [
    "KINDS",
    "STRATEGIES",
    "CurvePoint",
    "Interval",
    "Kind",
    "Labelled",
    "Learner",
    "LogScores",
    "PredictedStretch",
    "Round",
    "Snap",
    "Strategy",
    "Suggestion",
    "block_summary",
    "bootstrap_final_ratio",
    "candidates",
    "change_points",
    "class_weights",
    "coverage",
    "entropy",
    "highlight_intervals",
    "intervals",
    "margin_uncertainty",
    "mean_curve",
    "mutual_information",
    "normalised_tracks",
    "oracle",
    "predicted_stretches",
    "savings",
    "session_normaliser",
    "simulate",
    "smooth",
    "snap_range",
    "spans",
    "suggest",
    "table",
    "time_to_reach",
    "uncovered",
]
