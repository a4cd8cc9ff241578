"""What leaves the session: the export folder (model bundle, model card, ONNX step, label files, predictions, MCAP
beside each log, camera frames) and ``classify``, which runs an exported bundle on log files with no session.

``session_export`` writes the export; ``file_classify`` classifies files (a default-family bundle in NumPy, without
PyTorch); ``model_cards`` writes the card; ``export_staging`` is where an export is written before it is whole (a
locked ``.NAME.partial/``, swept once its export is dead). Names load on first use, so ``classify`` loads none of the
export's modules.
"""

from training import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "export_staging": ("check_target", "staged", "sweep_dead_exports"),
        "file_classify": (
            "OUTPUT_TYPES",
            "ReadLogs",
            "classify_files",
            "default_jobs",
            "load_for_scoring",
            "prediction_frame",
            "read_logs",
            "score_arrays",
        ),
        "model_cards": ("model_card",),
        "session_export": ("export_all", "write_labelled_frames"),
    },
    globals(),
)
