"""What a fit's numbers mean: folds that hold out blocks of time or whole logs, the metrics, and the estimates a
person reads (per terrain, which kind of figure it is, what a log is expected to score at its drift).

Modules: ``blocking`` (blocked folds with guards, folds by log), ``metrics`` (accuracy, balanced accuracy, calibration
error), ``estimates`` (the per-terrain estimate and its words), ``drift_accuracy`` (accuracy expected at a drift),
``unseen_runs`` (what the model that ships scores on a run it never saw, with an interval over runs). NumPy and
SciPy only: no torch is loaded here.
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "blocking": (
            "Block",
            "BlockedFolds",
            "LOG_FOLD_DRAWS",
            "blocked_folds",
            "cut_blocks",
            "deal_blocks",
            "log_folds",
        ),
        "estimates": (
            "HELD_OUT",
            "MISSED_RECALL",
            "MIXED",
            "NOT_MEASURED",
            "SAME_RUN",
            "estimate_headline",
            "estimate_table",
            "majority_words",
            "missed_terrains",
            "missed_words",
            "terrain_estimate",
            "terrain_recalls",
        ),
        "drift_accuracy": ("MIN_ROWS", "accuracy_by_drift", "expected_accuracy"),
        "metrics": ("classification_metrics", "expected_calibration_error"),
        "unseen_runs": ("FEW_RUNS", "UnseenRuns", "runs_low", "unseen_fell", "unseen_runs_figure", "unseen_words"),
    },
    globals(),
)
