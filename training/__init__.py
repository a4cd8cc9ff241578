"""The two-stage model (stage-1 predictor, stage-2 classifier), its training, scoring, export and evaluation.

Takes arrays, never sessions: ``workbench`` wires it to the session store.
"""

from . import distributed
from .bundle import BundleError, ModelBundle, load_bundle, save_bundle
from .checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from .config import FEATURE_MODES, ClassifierConfig, ElasticNet, FeatureMode, PredictorConfig, TrainConfig
from .data import Normalizer
from .fit_classifier import ClassifierFit, fit_classifier
from .fit_predictor import PredictorFit, fit_predictor
from .inference import LazyFeatures, Stage1Outputs, ensemble_pass, predictor_pass, run_classifiers, run_predictor
from .losses import classifier_loss, elastic_net, predictor_loss
from .models import Classifier, Predictor
from .progress import Cancelled, Progress
from .scoring import LogScores, entropy, score_log
from .stream import StreamingClassifier

__all__ = [
    "FEATURE_MODES",
    "BundleError",
    "Cancelled",
    "Checkpoint",
    "Classifier",
    "ClassifierConfig",
    "ClassifierFit",
    "ElasticNet",
    "FeatureMode",
    "LazyFeatures",
    "LogScores",
    "ModelBundle",
    "Normalizer",
    "Predictor",
    "PredictorConfig",
    "PredictorFit",
    "Progress",
    "Stage1Outputs",
    "StreamingClassifier",
    "TrainConfig",
    "classifier_loss",
    "distributed",
    "elastic_net",
    "ensemble_pass",
    "entropy",
    "fit_classifier",
    "fit_predictor",
    "load_bundle",
    "load_checkpoint",
    "predictor_loss",
    "predictor_pass",
    "run_classifiers",
    "run_predictor",
    "save_bundle",
    "save_checkpoint",
    "score_log",
]
