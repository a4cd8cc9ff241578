"""The session: a folder with an embedded SQLite store holding logs, labels and model versions.

Knows nothing of training, labelling strategies or the UI; ``workbench`` composes them.
"""

from .cameras import CameraFrame, CameraInfo
from .errors import IngestError, LabelError, SessionError, WorkbenchError
from .ingest import (
    AlignedLog,
    IngestOptions,
    Mapping,
    TimeColumn,
    align,
    load_mapping,
    plan_sources,
    read_mcap,
    read_source,
    sniff_csv,
)
from .label_files import write_frame
from .logs import Channel, Gap, HistoryEntry, LogInfo, Segment, Terrain
from .model_versions import ModelVersion
from .rowfiles import FileRows, NpyWriter
from .schema import KNOWN_TERRAIN_COLORS, SCHEMA_VERSION
from .store import Session

__all__ = [
    "KNOWN_TERRAIN_COLORS",
    "SCHEMA_VERSION",
    "AlignedLog",
    "CameraFrame",
    "CameraInfo",
    "Channel",
    "FileRows",
    "Gap",
    "HistoryEntry",
    "IngestError",
    "IngestOptions",
    "LabelError",
    "LogInfo",
    "Mapping",
    "ModelVersion",
    "NpyWriter",
    "Segment",
    "Session",
    "SessionError",
    "Terrain",
    "TimeColumn",
    "WorkbenchError",
    "align",
    "load_mapping",
    "plan_sources",
    "read_mcap",
    "read_source",
    "sniff_csv",
    "write_frame",
]
