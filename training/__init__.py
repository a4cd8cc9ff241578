"""The two-stage model (stage-1 predictor, stage-2 classifier): its training, passes over logs, streaming runtime,
ONNX export, bundles and evaluation protocols.

Takes arrays, never sessions: ``workbench`` wires it to the session store and scores logs with it.

Names are imported on first use (PEP 562): ``from training import TrainConfig`` loads ``training.config`` alone,
so a command that needs only settings (``workbench --help``, ``ingest``, ``labels``) never loads PyTorch.
"""

from __future__ import annotations

import importlib
from typing import Any

_MODULES: dict[str, tuple[str, ...]] = {
    "bundle": (
        "ModelBundle",
        "load_bundle",
        "parameter_count",
        "save_bundle",
    ),
    "checkpoint": (
        "Checkpoint",
        "load_checkpoint",
        "save_checkpoint",
    ),
    "config": (
        "ClassifierConfig",
        "ElasticNet",
        "FEATURE_MODES",
        "FeatureMode",
        "PredictorConfig",
        "TrainConfig",
        "WindowFitConfig",
        "to_dict",
    ),
    "data": (
        "Normalizer",
        "Piece",
        "cut_pieces",
        "neighbour_pairs",
        "stage1_batch",
    ),
    "evaluate_sequences": (
        "held_out_logs_protocol",
        "qcat_protocol",
    ),
    "evaluate_spectral": (
        "borealtc_window_protocol",
        "window_inputs",
    ),
    "evaluate_windows": (
        "FoldResult",
        "Split",
        "WindowProtocol",
        "borealtc_protocol",
        "labelled_subset",
        "outer_folds",
        "partitions",
        "windows",
    ),
    "classifier_fit": ("ClassifierFit", "fit_classifier"),
    "predictor_fit": ("PredictorFit", "fit_predictor", "split_pieces"),
    "fit_window": (
        "Stretch",
        "fit_window_classifier",
    ),
    "inference": (
        "LazyFeatures",
        "Stage1Outputs",
        "ensemble_pass",
        "padded_groups",
        "predictor_pass",
        "run_classifiers",
        "run_predictor",
    ),
    "losses": (
        "classifier_loss",
        "elastic_net",
        "predictor_loss",
    ),
    "metrics": (
        "classification_metrics",
        "expected_calibration_error",
    ),
    "models": (
        "Classifier",
        "Predictor",
    ),
    "onnx_export": (
        "check_onnx",
        "export_onnx",
        "run_onnx",
    ),
    "progress": (
        "CancelFn",
        "Cancelled",
        "Progress",
        "ProgressFn",
        "never",
    ),
    "spectral": (
        "SpectralConfig",
        "SpectralSteps",
        "SpectralStream",
        "frame_ends",
        "frame_features",
        "log_frames",
        "log_summaries",
        "per_step",
        "split_channels",
        "stacked_frames",
        "summary_windows",
    ),
    "stream": ("StreamingClassifier",),
    "training_errors": (
        "BundleError",
        "TrainingError",
    ),
    "window_classifier": (
        "WindowClassifier",
        "WindowClassifierConfig",
    ),
    "window_finetune": (
        "assign_folds",
        "fine_tune_window_classifier",
    ),
}
_OWNER = {name: module for module, names in _MODULES.items() for name in names}
_SUBMODULES = ("distributed",)

__all__ = sorted([*_OWNER, *_SUBMODULES])


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    module = _OWNER.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return __all__
