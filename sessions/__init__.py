"""The session: a folder with an embedded SQLite store holding logs, labels and model versions.

Knows nothing of training, labelling strategies or the UI; ``workbench`` composes them.
"""

from .cameras import CameraFrame, CameraInfo
from .checks import CHECK_KINDS, COUNTED_KINDS, Check
from .disk_space import check_room, folder_bytes
from .errors import IngestError, LabelError, SessionError, WorkbenchError
from .file_names import safe_file_name
from .ingest import (
    AlignedLog,
    ChannelSpec,
    DiscardRows,
    IngestOptions,
    Mapping,
    PoseTrack,
    Source,
    TimeColumn,
    align,
    load_mapping,
    local_metres,
    plan_sources,
    read_mcap,
    read_source,
    sniff_csv,
)
from .label_files import LabelImport, file_format, read_frame, write_frame
from .label_studio import CONTROL as LABEL_STUDIO_CONTROL
from .label_studio import OBJECT as LABEL_STUDIO_OBJECT
from .label_studio import label_studio_frame, task_log
from .limits import MAX_NAME_CHARS, MAX_RATE_HZ, name_refusal
from .logs import Channel, Gap, HistoryEntry, LogInfo, Segment, Terrain
from .model_versions import ModelVersion
from .new_files import check_new_target, check_new_targets, new_file, rename_new
from .path_mcap import TerrainPath, path_topics
from .rowfiles import FileRows, NpyWriter
from .schema import KNOWN_TERRAIN_COLORS, SCHEMA_VERSION
from .store import Session
from .terrain_mcap import (
    LABEL_TOPIC,
    PREDICTION_TOPIC,
    LogClock,
    TerrainPredictions,
    per_log_paths,
    refuse_existing,
    write_terrain_mcap,
)

__all__ = [
    "CHECK_KINDS",
    "COUNTED_KINDS",
    "KNOWN_TERRAIN_COLORS",
    "LABEL_STUDIO_CONTROL",
    "LABEL_STUDIO_OBJECT",
    "LABEL_TOPIC",
    "MAX_NAME_CHARS",
    "MAX_RATE_HZ",
    "PREDICTION_TOPIC",
    "SCHEMA_VERSION",
    "AlignedLog",
    "CameraFrame",
    "CameraInfo",
    "Channel",
    "ChannelSpec",
    "Check",
    "DiscardRows",
    "FileRows",
    "Gap",
    "HistoryEntry",
    "IngestError",
    "IngestOptions",
    "LabelError",
    "LabelImport",
    "LogClock",
    "LogInfo",
    "Mapping",
    "ModelVersion",
    "NpyWriter",
    "PoseTrack",
    "Segment",
    "Session",
    "SessionError",
    "Source",
    "Terrain",
    "TerrainPath",
    "TerrainPredictions",
    "TimeColumn",
    "WorkbenchError",
    "align",
    "check_new_target",
    "check_new_targets",
    "check_room",
    "file_format",
    "folder_bytes",
    "label_studio_frame",
    "load_mapping",
    "local_metres",
    "name_refusal",
    "new_file",
    "path_topics",
    "per_log_paths",
    "plan_sources",
    "read_frame",
    "read_mcap",
    "read_source",
    "refuse_existing",
    "rename_new",
    "safe_file_name",
    "sniff_csv",
    "task_log",
    "write_frame",
    "write_terrain_mcap",
]
