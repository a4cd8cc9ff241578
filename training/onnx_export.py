"""ONNX model of the streaming classifier: one sample and the recurrent state in, probabilities and new state out."""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np
import torch

from .bundle import ModelBundle
from .stream import StepModel, StreamingClassifier
from .window_step import WindowStepModel, window_zero_state

INPUTS = ("x", "h1", "c1", "h2", "c2", "prev", "started")
OUTPUTS = ("probs", "h1_out", "c1_out", "h2_out", "c2_out", "prev_out")
WINDOW_INPUTS = ("x", "ring", "count", "frames", "n_frames")  # the default family's step
WINDOW_OUTPUTS = ("probs", "ring_out", "count_out", "frames_out", "n_frames_out")


def io_names(bundle: ModelBundle) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The exported step's input and output names: the state a robot's loop carries differs by family."""
    return (WINDOW_INPUTS, WINDOW_OUTPUTS) if bundle.family == "default" else (INPUTS, OUTPUTS)


def zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``."""
    if bundle.family == "default":
        return window_zero_state(bundle, streams)
    m, c = len(bundle.classifiers), len(bundle.channels)
    h1, h2 = bundle.predictor.config.hidden, bundle.classifiers[0].config.hidden
    z = np.zeros
    return {
        "h1": z((streams, h1), np.float32),
        "c1": z((streams, h1), np.float32),
        "h2": z((m, streams, h2), np.float32),
        "c2": z((m, streams, h2), np.float32),
        "prev": z((streams, c), np.float32),
        "started": z((streams, 1), np.float32),
    }


def export_onnx(bundle: ModelBundle, path: str | Path) -> Path:
    """Write the one-step model to ``path`` with a dynamic number of streams."""
    model = (WindowStepModel(bundle) if bundle.family == "default" else StepModel(bundle)).eval()
    inputs, outputs = io_names(bundle)
    args = tuple(
        torch.from_numpy(v)
        for v in {"x": np.zeros((2, len(bundle.channels)), np.float32), **zero_state(bundle, 2)}.values()
    )
    batch = torch.export.Dim("streams", min=1, max=4096)
    if bundle.family == "default":
        shapes = tuple({0: batch} for _ in inputs)
    else:
        shapes = ({0: batch}, {0: batch}, {0: batch}, {1: batch}, {1: batch}, {0: batch}, {0: batch})
    onnx_log = logging.getLogger("torch.onnx")
    level = onnx_log.level
    onnx_log.setLevel(logging.ERROR)  # "torchvision is not installed" and similar are not the user's business
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        program = torch.onnx.export(
            model,
            args,
            input_names=list(inputs),
            output_names=list(outputs),
            dynamic_shapes=shapes,
            dynamo=True,
            verbose=False,
        )
    onnx_log.setLevel(level)
    path = Path(path)
    program.save(str(path))
    return path


def run_onnx(path: str | Path, bundle: ModelBundle, samples: np.ndarray) -> np.ndarray:
    """Run an exported model over a ``(T, C)`` log of one stream with onnxruntime: ``(T, K)``."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    inputs, outputs = io_names(bundle)
    feed = zero_state(bundle, 1)
    out = np.empty((len(samples), len(bundle.classes)), np.float32)
    for t, x in enumerate(np.asarray(samples, np.float32)):
        probs, *state = session.run(list(outputs), {"x": x[None], **feed})
        feed = dict(zip(inputs[1:], state, strict=False))  # each state output feeds its input back
        if bundle.family != "default":
            feed["started"] = np.ones((1, 1), np.float32)
        out[t] = probs[0]
    return out


def check_onnx(path: str | Path, bundle: ModelBundle, samples: np.ndarray) -> float:
    """Largest absolute difference between ONNX Runtime and the streaming runtime over ``samples``."""
    ours = StreamingClassifier(bundle).run(samples)
    return float(np.abs(run_onnx(path, bundle, samples) - ours).max())
