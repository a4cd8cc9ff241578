"""What leaves the session: the export folder (model bundle, model card, ONNX step, label files, predictions, MCAP
beside each log, camera frames) and ``classify``, which runs an exported bundle on log files with no session.

``session_export`` writes and classifies; ``model_card`` writes the card; ``export_staging`` is where an export is
written before it is whole (a locked ``.NAME.partial/``, swept once its export is dead).
"""

from .export_staging import check_target, staged, sweep_dead_exports
from .model_card import model_card
from .session_export import (
    OUTPUT_TYPES,
    ReadLogs,
    classify_files,
    export_all,
    prediction_frame,
    read_logs,
    score_arrays,
    write_labelled_frames,
)

__all__ = [
    "OUTPUT_TYPES",
    "ReadLogs",
    "check_target",
    "classify_files",
    "export_all",
    "model_card",
    "prediction_frame",
    "read_logs",
    "score_arrays",
    "staged",
    "sweep_dead_exports",
    "write_labelled_frames",
]
