"""Where each terrain was: the logs' paths coloured by terrain, drawn for the export, the page and Foxglove."""

from .map_picture import write_map_picture
from .session_map import MAP_FILE, TerrainMap
from .terrain_paths import (
    LABEL,
    MODEL,
    UNSURE,
    LogPath,
    best_track,
    class_colours,
    colour_of,
    first_fix,
    log_path,
    panel_of,
    stretches,
    terrain_path,
)

__all__ = [
    "LABEL",
    "MAP_FILE",
    "MODEL",
    "UNSURE",
    "LogPath",
    "TerrainMap",
    "best_track",
    "class_colours",
    "colour_of",
    "first_fix",
    "log_path",
    "panel_of",
    "stretches",
    "terrain_path",
    "write_map_picture",
]
