"""What ships to a robot: load a bundle (``bundle``; ``bundle_files`` its files' checks), run it one sample at a time
(``stream``, with an optional HMM over its probabilities: ``terrain_filter``), score log files with a default-family
bundle in NumPy alone (``scoring_bundle``), export it to ONNX and check the export against the stream
(``onnx_export``). A person integrating the model on a robot reads this room; the families' rooms say how the models
are built and trained.

Used through ``training`` (``from training import StreamingClassifier, load_bundle``), whose names load on first use;
so do this room's: ``load_scoring_bundle`` never loads PyTorch.
"""

from ..lazy_names import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "bundle": ("ModelBundle", "load_bundle", "parameter_count", "save_bundle"),
        "onnx_export": ("check_onnx", "export_onnx", "run_onnx"),
        "scoring_bundle": ("ScoringBundle", "load_scoring_bundle"),
        "stream": ("StreamingClassifier",),
        "terrain_filter": ("MAX_DWELL_S", "TerrainFilter"),
    },
    globals(),
)
