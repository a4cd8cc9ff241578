"""The default family: short-time spectra of the signals and a small convolutional network over them.

A causal front end (:mod:`.spectra`) turns each log into frames: log power spectra of 0.4 s windows of the fast
channels and the level and range of the slow ones, one frame every 0.2 s. Stage 2 (:mod:`.window_classifier`) reads
a step's last 7 frames (1.6 s): a 1x1 convolution, a 3-frame convolution, their mean and spread, a linear layer;
k fold models form the ensemble. It is fitted on the labelled segments and, by self-training, on unlabelled
stretches whose frames agree (:mod:`.fit_window`); the UI's quick Retrain fine-tunes the fold models on new labels
(:mod:`.window_finetune`). :mod:`.window_step` runs it one sample at a time (NumPy for the robot, PyTorch for ONNX).
Its stage 1 (:mod:`.frame_predictor`: the surprise highlight, the suggestions' embeddings) predicts the next frame
from the ones before, trained on all logs without labels; :mod:`.frame_outputs` reads its per-frame outputs per step.

Modules: ``spectra`` (the front end), ``window_config`` (fit settings), ``window_augment`` (run-to-run changes drawn
on training rows), ``window_classifier`` (the network), ``fit_window`` / ``window_finetune`` (the fits),
``stretch_pool`` (self-training's rows of the unlabelled stretches), ``window_rows`` (their labelled rows, held as
the frames they read), ``window_calibration`` (the ensemble's temperature), ``drift_reference`` and
``window_drift`` (how unlike the labelled frames a step is), ``frame_scores`` (the members and the drift once per
frame), ``frame_numpy`` (the same in NumPy: scoring files without PyTorch), ``kinds`` (the modules' names in a
bundle's config), ``window_step`` (one sample at a time), ``frame_predictor`` (a stage 1 over the frames: the
next frame from the ones before), ``frame_outputs`` (its outputs per sample step), ``cnn_family`` (what the
registry reads).
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "spectra": (
            "SpectralConfig",
            "SpectralSteps",
            "SpectralStream",
            "drop_pages",
            "frame_ends",
            "frame_features",
            "log_frames",
            "log_summaries",
            "per_step",
            "segment_features",
            "split_channels",
            "stacked_frames",
            "summary_windows",
        ),
        "window_config": ("RowAugment", "WindowFitConfig"),
        "window_augment": ("augment_rows",),
        "window_classifier": ("WindowClassifier", "WindowClassifierConfig"),
        "fit_window": ("block_and_guard", "fit_window_classifier", "predict_steps"),
        "window_train": ("train_rows",),
        "stretch_pool": ("Stretch", "frame_rows"),
        "window_finetune": ("assign_folds", "fine_tune_window_classifier"),
        "window_calibration": ("fit_temperature", "scale_head"),
        "drift_reference": ("DRIFTED", "DriftReference"),
        "window_drift": ("drift_of_log", "drift_of_rows", "fit_drift"),
        "frame_numpy": ("FrameChunk", "NumpyMembers", "step_frames"),
        "frame_scores": ("blank_probs", "frame_chunks"),
        "window_step": ("WindowStep", "WindowStepModel"),
        "frame_outputs": ("FrameOutputs", "StepRows"),
        "kinds": ("FRAME_PREDICTOR_KIND", "WINDOW_KIND"),
        "frame_predictor": (
            "FramePredictor",
            "FramePredictorConfig",
            "FramePredictorFit",
            "copy_last_error",
            "fit_frame_predictor",
            "frame_surprise",
        ),
        "cnn_family": ("FAMILY",),
    },
    globals(),
)
