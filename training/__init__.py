"""Terrain models in families, each in a room of its own, and the machinery they share.

Rooms (one per family, found by name through :mod:`.registry`):
    ``spectral_cnn``  the default family: short-time spectra and a small convolutional network (``--model default``)
    ``paper_lstm``    the paper's two stacked LSTMs (``--model paper``)
    ``minirocket``    MiniRocket's fixed convolutions and a ridge head (``--model minirocket``)
and ``runtime``, what ships to a robot: ``bundle`` (a model as files), ``stream`` (one sample at a time),
``onnx_export``. Two rooms hold what every family shares:
    ``figures``  what a fit's numbers mean: ``blocking`` (folds by blocks of time and by log), ``metrics``,
                 ``estimates`` (per terrain, and which kind of figure), ``drift_accuracy`` (accuracy at a drift)
    ``running``  how fits run: ``cpu_threads``, ``fit_threads``, ``fit_processes``, ``distributed`` (``torchrun``),
                 ``checkpoint``, ``progress``

At this level: ``registry`` (family name -> room), ``passes`` (stage 2 over whole logs), ``fitting`` (what every
stage-2 fit returns), ``normalizer``, ``training_errors``, ``lazy_names``.

Takes arrays, never sessions: ``workbench`` wires it to the session store and scores logs with it. The evaluation
protocols (BorealTC, QCAT, held-out logs) live with the datasets they read, in ``workbench.evaluation``.

Names are imported on first use (PEP 562): ``from training import TrainConfig`` loads the paper family's config
module alone, so a command that needs only settings (``workbench --help``, ``ingest``, ``labels``) never loads
PyTorch.
"""

from . import figures, running  # their __init__s load no module until a name is asked for
from .lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        # the shared machinery
        "registry": (
            "DEFAULT_FAMILY",
            "FAMILY_ROOMS",
            "Family",
            "UNNAMED_FAMILY",
            "device_refusal",
            "family",
            "family_names",
            "recorded_family",
        ),
        "runtime": (
            "MAX_DWELL_S",
            "ModelBundle",
            "ScoringBundle",
            "StreamingClassifier",
            "TerrainFilter",
            "check_onnx",
            "export_onnx",
            "load_bundle",
            "load_scoring_bundle",
            "parameter_count",
            "run_onnx",
            "save_bundle",
        ),
        "fitting": ("ClassifierFit", "Segment", "fold_indices", "to_dict"),
        # the shared rooms' names, as each room's __init__ lists them (training.distributed is a module of its own)
        "figures": tuple(figures.__all__),
        "running": tuple(n for n in running.__all__ if n != "distributed"),
        "normalizer": ("Normalizer", "Rows"),
        "passes": ("ensemble_pass", "padded_groups", "run_classifiers"),
        "training_errors": ("BundleError", "TrainingError"),
        "lazy_names": ("lazy_exports",),  # the same for workbench's rooms
        # the paper family's room
        "paper_lstm": (
            "Classifier",
            "ClassifierConfig",
            "ElasticNet",
            "FEATURE_MODES",
            "FeatureMode",
            "LazyFeatures",
            "Piece",
            "Predictor",
            "PredictorConfig",
            "PredictorFit",
            "Stage1Outputs",
            "TrainConfig",
            "classifier_loss",
            "cut_pieces",
            "elastic_net",
            "fit_classifier",
            "fit_predictor",
            "neighbour_pairs",
            "predictor_loss",
            "predictor_pass",
            "run_predictor",
            "split_pieces",
            "stage1_batch",
        ),
        # the default family's room
        "spectral_cnn": (
            "DRIFTED",
            "DriftReference",
            "FRAME_PREDICTOR_KIND",
            "FrameChunk",
            "FrameOutputs",
            "FramePredictor",
            "FramePredictorConfig",
            "FramePredictorFit",
            "NumpyMembers",
            "RowAugment",
            "SpectralConfig",
            "SpectralSteps",
            "SpectralStream",
            "StepRows",
            "Stretch",
            "WindowClassifier",
            "WindowClassifierConfig",
            "WindowFitConfig",
            "assign_folds",
            "augment_rows",
            "blank_probs",
            "block_and_guard",
            "copy_last_error",
            "drift_of_log",
            "drift_of_rows",
            "fine_tune_window_classifier",
            "fit_drift",
            "fit_frame_predictor",
            "frame_chunks",
            "frame_surprise",
            "fit_temperature",
            "scale_head",
            "fit_window_classifier",
            "drop_pages",
            "frame_ends",
            "frame_features",
            "log_frames",
            "log_summaries",
            "per_step",
            "split_channels",
            "stacked_frames",
            "step_frames",
            "summary_windows",
        ),
        # MiniRocket's room
        "minirocket": (
            "ROCKET_KIND",
            "RawSteps",
            "RocketClassifier",
            "RocketClassifierConfig",
            "RocketConfig",
            "RocketParameters",
            "RocketTransform",
            "aeon_parameters",
            "fit_rocket",
            "fit_rocket_classifier",
            "fit_rocket_steps",
            "rocket_features",
        ),
    },
    globals(),
    submodules=("running.distributed",),
)
