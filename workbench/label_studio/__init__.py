"""The session as a Label Studio ML backend (``workbench label-studio``): pre-annotations of the model's stretches
in the workbench's order, and Label Studio's annotations as the session's labels."""

from .backend import SOURCE, Backend
from .http_server import MAX_BODY, BackendServer
from .label_config import LabelConfig, parse_label_config
from .serving import serve_label_studio

__all__ = [
    "MAX_BODY",
    "SOURCE",
    "Backend",
    "BackendServer",
    "LabelConfig",
    "parse_label_config",
    "serve_label_studio",
]
