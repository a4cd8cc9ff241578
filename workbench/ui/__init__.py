"""The browser workbench on viser: shared state and training job, one view per browser, one module per panel."""

from .app import WorkbenchApp
from .jobs import JobStatus, TrainJob
from .state import Queued, SharedState, score_and_keep
from .uploads import MAX_UPLOAD_MB, safe_name
from .view import ClientView

__all__ = [
    "MAX_UPLOAD_MB",
    "ClientView",
    "JobStatus",
    "Queued",
    "SharedState",
    "TrainJob",
    "WorkbenchApp",
    "safe_name",
    "score_and_keep",
]
