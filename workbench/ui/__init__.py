"""The browser workbench on viser: shared state and training job, one view per browser, one module per panel."""

from .app import WorkbenchApp
from .jobs import JobStatus, TrainJob
from .map_view import MapView, ground_point, map_bounds, map_paths, nearest_pose, segment_colours
from .score_keep import score_and_keep
from .session_watch import watch_session
from .state import Queued, SharedState
from .torch_lane import LANE, TorchLane
from .uploads import MAX_UPLOAD_MB, safe_name
from .view import ClientView

__all__ = [
    "LANE",
    "MAX_UPLOAD_MB",
    "ClientView",
    "JobStatus",
    "MapView",
    "Queued",
    "SharedState",
    "TorchLane",
    "TrainJob",
    "WorkbenchApp",
    "ground_point",
    "map_bounds",
    "map_paths",
    "nearest_pose",
    "safe_name",
    "score_and_keep",
    "segment_colours",
    "watch_session",
]
