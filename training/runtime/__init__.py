"""What ships to a robot: load a bundle (``bundle``), run it one sample at a time (``stream``, with an optional HMM
over its probabilities: ``terrain_filter``), export it to ONNX and check the export against the stream
(``onnx_export``). A person integrating the model on a robot reads this room; the families' rooms say how the models
are built and trained.

Used through ``training`` (``from training import StreamingClassifier, load_bundle``), whose names load on first use.
"""

from .bundle import ModelBundle, load_bundle, parameter_count, save_bundle
from .onnx_export import check_onnx, export_onnx, run_onnx
from .stream import StreamingClassifier
from .terrain_filter import MAX_DWELL_S, TerrainFilter

__all__ = [
    "MAX_DWELL_S",
    "ModelBundle",
    "StreamingClassifier",
    "TerrainFilter",
    "check_onnx",
    "export_onnx",
    "load_bundle",
    "parameter_count",
    "run_onnx",
    "save_bundle",
]
