"""The human-in-the-loop cycle without a UI: train the stages and save versions, cache what stage 2 reads, score every
log along one path, keep the last scoring, rank what to label next. The UI, the CLI, the export and the evaluation call
it; it composes ``sessions`` (data, labels, versions), ``training`` (models, arrays only) and ``labeling``
(suggestions).

Modules: ``train_stages`` (stage 1 and stage 2 of any family, versions, the active models), ``frame_stage1`` (the
default family's stage 1, and which stage 1 a family trains), ``stage_inputs`` (stage 1's cache per predictor version,
the paper family's stage-2 features, change points), ``front_end`` (the spectral frames per log, the unlabelled
stretches self-training reads), ``scores`` (the one scoring path), ``score_store`` (the last scoring kept in the
session), ``change_point_store`` (each log's change points kept per predictor), ``suggestions`` (the queue),
``checks_record`` (each label first a check of the model: test then train), ``family_choice`` (``--model auto``: every
family over the default stage 1 fitted, the one the session's held-out evidence favours kept), ``session_figure`` (how
right the session is now: the active version's spot checks corrected by its confidence), ``unseen_change`` (whether a
new version's figure for a run it never saw fell below the last one's interval).
"""

from .answer_change import AnswerChange, answer_change, keep_answers
from .change_point_store import keep_change_points, kept_change_points
from .checks_record import (
    ChecksSummary,
    checks_summary,
    estimate_disagrees,
    names_now,
    piece_answer,
    record_check,
)
from .family_choice import FamilyChoice, auto_families, train_best_classifier
from .frame_stage1 import train_frame_predictor, train_stage1
from .front_end import (
    STRETCH_S,
    choose_front_end,
    free_stretches,
    in_memory_features,
    log_frame_files,
    spectral_features,
    stretch_units,
    unlabelled_stretches,
    window_features,
    window_sizes,
)
from .score_store import (
    GROUP_STEPS,
    StoredScores,
    log_groups,
    queue_key,
    score_and_store,
    store_queue,
    store_scores,
    stored_queue,
    stored_scores,
)
from .scores import EMBEDDING_MODE, SessionScores, compute_scores, score_logs, score_session, stage1_embedding
from .session_figure import DEFAULT_WIDTH, FigureTally, SessionFigure, SessionFigures, session_figures
from .stage2_fit import STAGE1_FEATURES, taught_classes, train_classifier
from .stage_inputs import (
    consistency_pairs,
    log_change_points,
    signal_change_points,
    stage1_cached,
    stage1_outputs,
    stage2_features,
)
from .suggestions import (
    QUEUE_MODES,
    SESSION_POLICY,
    SUGGESTION_S,
    VERIFY,
    suggest_for_session,
    suggestion_lengths,
    verification_queue,
)
from .train_stages import (
    MODEL_FAMILIES,
    active_bundle,
    active_predictor,
    classifier_family,
    follow_predictor_training,
    front_end_of,
    model_logs,
    require_stage1,
    stage1_family,
    train_predictor,
)
from .unseen_change import unseen_change

__all__ = [
    "DEFAULT_WIDTH",
    "EMBEDDING_MODE",
    "GROUP_STEPS",
    "MODEL_FAMILIES",
    "QUEUE_MODES",
    "SESSION_POLICY",
    "STAGE1_FEATURES",
    "STRETCH_S",
    "SUGGESTION_S",
    "VERIFY",
    "AnswerChange",
    "ChecksSummary",
    "FamilyChoice",
    "FigureTally",
    "SessionFigure",
    "SessionFigures",
    "SessionScores",
    "StoredScores",
    "active_bundle",
    "active_predictor",
    "answer_change",
    "auto_families",
    "checks_summary",
    "choose_front_end",
    "classifier_family",
    "compute_scores",
    "consistency_pairs",
    "estimate_disagrees",
    "follow_predictor_training",
    "free_stretches",
    "front_end_of",
    "in_memory_features",
    "keep_answers",
    "keep_change_points",
    "kept_change_points",
    "log_change_points",
    "log_frame_files",
    "log_groups",
    "model_logs",
    "names_now",
    "piece_answer",
    "queue_key",
    "record_check",
    "require_stage1",
    "score_and_store",
    "score_logs",
    "score_session",
    "session_figures",
    "signal_change_points",
    "spectral_features",
    "stage1_cached",
    "stage1_embedding",
    "stage1_family",
    "stage1_outputs",
    "stage2_features",
    "store_queue",
    "store_scores",
    "stored_queue",
    "stored_scores",
    "stretch_units",
    "suggest_for_session",
    "suggestion_lengths",
    "taught_classes",
    "train_best_classifier",
    "train_classifier",
    "train_frame_predictor",
    "train_predictor",
    "train_stage1",
    "unlabelled_stretches",
    "unseen_change",
    "verification_queue",
    "window_features",
    "window_sizes",
]
