"""The human-in-the-loop cycle without a UI: train the stages and save versions, cache what stage 2 reads, score every
log along one path, keep the last scoring, rank what to label next. The UI, the CLI, the export and the evaluation call
it; it composes ``sessions`` (data, labels, versions), ``training`` (models, arrays only) and ``labeling``
(suggestions).

Modules: ``train_stages`` (stage 1 and stage 2 of any family, versions, the active models), ``frame_stage1`` (the
default family's stage 1, and which stage 1 a family trains), ``stage_inputs`` (stage 1's cache per predictor version,
the paper family's stage-2 features), ``front_end`` (the spectral frames per log, the unlabelled stretches
self-training reads), ``scores`` (the one scoring path; ``frame_reduce`` a frame's answer over its steps),
``score_store`` (the last scoring kept in the session; ``score_files`` its files, ``forked_scores`` hours of logs
scored in a forked process per core), ``change_point_store`` (each log's change points, kept per
predictor), ``suggestions`` (the queue), ``checks_record`` (each label first a check of the model: test then train),
``family_choice`` (``--model auto``: every family over the default stage 1 fitted, the one the session's held-out
evidence favours kept), ``session_figure`` (how right the session is now: the active version's spot checks corrected
by its confidence), ``unseen_changes`` (whether a new version's figure for a run it never saw fell below the last one's
interval), ``taught_fit`` (the model that ships: the active version taught by what the session knows, kept beside it).

Names load on first use (PEP 562, as ``training``'s): ``classify`` reads its checks and change points from here
without loading PyTorch.
"""

from training import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "answer_changes": (
            "AnswerChange",
            "answer_change",
            "keep_answers",
        ),
        "change_point_store": (
            "keep_change_points",
            "kept_change_points",
            "log_change_points",
        ),
        "checks_record": (
            "ChecksSummary",
            "checks_summary",
            "estimate_disagrees",
            "names_now",
            "piece_answer",
            "record_check",
        ),
        "family_choice": (
            "FamilyChoice",
            "auto_families",
            "train_best_classifier",
        ),
        "forked_scores": ("scored_in_processes", "scoring_processes"),
        "frame_stage1": (
            "train_frame_predictor",
            "train_stage1",
        ),
        "frame_reduce": ("frame_log_scores",),
        "front_end": (
            "STRETCH_S",
            "choose_front_end",
            "free_stretches",
            "in_memory_features",
            "log_frame_files",
            "spectral_features",
            "stretch_units",
            "unlabelled_stretches",
            "window_features",
            "window_sizes",
        ),
        "score_files": ("GROUP_STEPS", "log_groups"),
        "score_store": (
            "StoredScores",
            "queue_key",
            "score_and_store",
            "store_queue",
            "store_scores",
            "stored_queue",
            "stored_scores",
        ),
        "scores": (
            "EMBEDDING_MODE",
            "SessionScores",
            "compute_scores",
            "score_logs",
            "score_session",
            "stage1_embedding",
        ),
        "session_figure": (
            "DEFAULT_WIDTH",
            "FigureTally",
            "SessionFigure",
            "SessionFigures",
            "session_figures",
        ),
        "stage2_fit": (
            "STAGE1_FEATURES",
            "taught_classes",
            "train_classifier",
        ),
        "stage_inputs": (
            "consistency_pairs",
            "signal_change_points",
            "stage1_cached",
            "stage1_outputs",
            "stage2_features",
        ),
        "suggestions": (
            "QUEUE_MODES",
            "SESSION_POLICY",
            "SUGGESTION_S",
            "VERIFY",
            "suggest_for_session",
            "suggestion_lengths",
            "verification_queue",
        ),
        "taught_fit": ("kept_taught", "labels_key", "shipped_version", "teachable"),
        "train_stages": (
            "MODEL_FAMILIES",
            "active_bundle",
            "active_predictor",
            "classifier_family",
            "follow_predictor_training",
            "front_end_of",
            "model_logs",
            "require_stage1",
            "stage1_family",
            "train_predictor",
        ),
        "unseen_changes": ("unseen_change",),
    },
    globals(),
)
