"""The two-stage model (stage-1 predictor, stage-2 classifier): its training, passes over logs, streaming runtime,
ONNX export, bundles and evaluation protocols.

Takes arrays, never sessions: ``workbench`` wires it to the session store and scores logs with it.
"""

from . import distributed
from .bundle import ModelBundle, load_bundle, parameter_count, save_bundle
from .checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from .config import FEATURE_MODES, ClassifierConfig, ElasticNet, FeatureMode, PredictorConfig, TrainConfig, to_dict
from .data import Normalizer, Piece, cut_pieces, neighbour_pairs, stage1_batch
from .evaluate_sequences import held_out_logs_protocol, qcat_protocol
from .evaluate_spectral import borealtc_window_protocol, window_inputs
from .evaluate_windows import (
    FoldResult,
    Split,
    WindowProtocol,
    borealtc_protocol,
    labelled_subset,
    outer_folds,
    partitions,
    windows,
)
from .fit_classifier import ClassifierFit, fit_classifier
from .fit_predictor import PredictorFit, fit_predictor, split_pieces
from .fit_window import Stretch, WindowFitConfig, fit_window_classifier
from .inference import (
    LazyFeatures,
    Stage1Outputs,
    ensemble_pass,
    padded_groups,
    predictor_pass,
    run_classifiers,
    run_predictor,
)
from .losses import classifier_loss, elastic_net, predictor_loss
from .metrics import classification_metrics, expected_calibration_error
from .models import Classifier, Predictor
from .onnx_export import check_onnx, export_onnx, run_onnx
from .progress import CancelFn, Cancelled, Progress, ProgressFn, never
from .spectral import (
    SpectralConfig,
    SpectralSteps,
    SpectralStream,
    frame_ends,
    frame_features,
    log_frames,
    log_summaries,
    per_step,
    split_channels,
    stacked_frames,
    summary_windows,
)
from .stream import StreamingClassifier
from .training_errors import BundleError, TrainingError
from .window_classifier import WindowClassifier, WindowClassifierConfig

__all__ = [
    "FEATURE_MODES",
    "BundleError",
    "CancelFn",
    "Cancelled",
    "Checkpoint",
    "Classifier",
    "ClassifierConfig",
    "ClassifierFit",
    "ElasticNet",
    "FeatureMode",
    "FoldResult",
    "LazyFeatures",
    "ModelBundle",
    "Normalizer",
    "Piece",
    "Predictor",
    "PredictorConfig",
    "PredictorFit",
    "Progress",
    "ProgressFn",
    "SpectralConfig",
    "SpectralSteps",
    "SpectralStream",
    "Split",
    "Stage1Outputs",
    "StreamingClassifier",
    "Stretch",
    "TrainConfig",
    "TrainingError",
    "WindowClassifier",
    "WindowClassifierConfig",
    "WindowFitConfig",
    "WindowProtocol",
    "borealtc_protocol",
    "borealtc_window_protocol",
    "check_onnx",
    "classification_metrics",
    "classifier_loss",
    "cut_pieces",
    "distributed",
    "elastic_net",
    "ensemble_pass",
    "expected_calibration_error",
    "export_onnx",
    "fit_classifier",
    "fit_predictor",
    "fit_window_classifier",
    "frame_ends",
    "frame_features",
    "held_out_logs_protocol",
    "labelled_subset",
    "load_bundle",
    "load_checkpoint",
    "log_frames",
    "log_summaries",
    "neighbour_pairs",
    "never",
    "outer_folds",
    "padded_groups",
    "parameter_count",
    "partitions",
    "per_step",
    "predictor_loss",
    "predictor_pass",
    "qcat_protocol",
    "run_classifiers",
    "run_onnx",
    "run_predictor",
    "save_bundle",
    "save_checkpoint",
    "split_channels",
    "split_pieces",
    "stacked_frames",
    "stage1_batch",
    "summary_windows",
    "to_dict",
    "window_inputs",
    "windows",
]
