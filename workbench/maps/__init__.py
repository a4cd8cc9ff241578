"""Where each terrain was: the logs' paths coloured by terrain, drawn for the export, the page and Foxglove."""

from .map_picture import write_map_picture
from .session_map import MAP_FILE, TerrainMap
from .terrain_paths import LABEL, MODEL, UNSURE, LogPath, best_track, first_fix, log_path, panel_of, stretches

__all__ = [
    "LABEL",
    "MAP_FILE",
    "MODEL",
    "UNSURE",
    "LogPath",
    "TerrainMap",
    "best_track",
    "first_fix",
    "log_path",
    "panel_of",
    "stretches",
    "write_map_picture",
]
