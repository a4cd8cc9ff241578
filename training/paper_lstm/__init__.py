"""The paper's family (Kumar et al., "Loss Regularizing Robotic Terrain Classification"): two stacked LSTMs.

Stage 1, :class:`Predictor`, an LSTM estimating each sample from the ones before it, trained on every log without
labels (elastic-net regularised MSE) and frozen; stage 2, :class:`Classifier`, an LSTM on stage 1's hidden states
and errors trained on the labelled segments (elastic-net regularised cross-entropy), k fold models as an ensemble.
``workbench train --model paper``. Until the default family has a stage 1 of its own, its surprise highlight and
suggestion embeddings come from this family's predictor too.

Modules: ``lstm_config`` (sizes, training settings), ``lstm_models`` (the modules), ``lstm_losses``, ``pieces``
(batches of log pieces), ``predictor_fit`` / ``classifier_fit`` (the fits), ``stage1_pass`` (stage 1 over whole
logs), ``lstm_step`` / ``fused_step`` (one sample at a time: PyTorch for ONNX, NumPy for the robot),
``lstm_family`` (what the registry reads).
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "lstm_config": (
            "ClassifierConfig",
            "ElasticNet",
            "FEATURE_MODES",
            "FeatureMode",
            "PredictorConfig",
            "TrainConfig",
        ),
        "lstm_models": ("Classifier", "Predictor", "feature_moments", "feature_width", "stage1_features"),
        "lstm_losses": ("classifier_loss", "consistency_loss", "elastic_net", "masked_mse", "predictor_loss"),
        "pieces": ("Piece", "cut_pieces", "labelled_pieces", "neighbour_pairs", "stage1_batch", "stage2_batch"),
        "predictor_fit": ("PredictorFit", "fit_predictor", "split_pieces"),
        "classifier_fit": ("balanced_weights", "fit_classifier"),
        "stage1_pass": ("LazyFeatures", "Stage1Outputs", "predictor_pass", "run_predictor"),
        "fused_step": ("Bf16Step", "FusedStep"),
        "lstm_step": ("StepModel",),
        "lstm_family": ("FAMILY",),
    },
    globals(),
)
