"""ONNX model of the streaming classifier: one sample and the recurrent state in, probabilities and new state out."""

from __future__ import annotations

import logging
import warnings
from pathlib import Path

import numpy as np
import torch

from .bundle import ModelBundle
from .stream import StreamingClassifier


def export_onnx(bundle: ModelBundle, path: str | Path, *, dynamo: bool | None = None) -> Path:
    """Write the bundle's one-step model (its family's ``step_module``) to ``path`` with a dynamic number of
    streams.

    Args:
        bundle: The model.
        path: The ``.onnx`` file to write.
        dynamo: Which of torch's exporters: ``False`` the TorchScript one, ``True`` the ``torch.export`` one;
            ``None``: the TorchScript one while the installed torch has it, else the other. Both give the same
            graph's numbers (every export is checked against onnxruntime by :func:`check_onnx`), but the TorchScript
            one takes 0.3 s where ``torch.export`` takes 9 s (most of ``workbench export`` on 2 cores); torch has
            deprecated it, so a torch without it gets the other with no change here.
    """
    family = bundle.stage2_family()
    model = family.step_module(bundle).eval()
    inputs, outputs = family.onnx_inputs, family.onnx_outputs
    args = tuple(
        torch.from_numpy(v)
        for v in {"x": np.zeros((2, len(bundle.channels)), np.float32), **family.zero_state(bundle, 2)}.values()
    )
    path = Path(path)
    if dynamo is None:
        dynamo = not _has_torchscript_exporter()
    onnx_log = logging.getLogger("torch.onnx")
    level = onnx_log.level
    onnx_log.setLevel(logging.ERROR)  # "torchvision is not installed" and similar are not the user's business
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and constant-folding notes
            if dynamo:
                batch = torch.export.Dim("streams", min=1, max=4096)
                program = torch.onnx.export(
                    model,
                    args,
                    input_names=list(inputs),
                    output_names=list(outputs),
                    dynamic_shapes=tuple({axis: batch} for axis in family.stream_axes),
                    dynamo=True,
                    verbose=False,
                )
                program.save(str(path))
            else:
                axes = dict(zip(inputs, family.stream_axes, strict=True))
                # probs counts streams on its first axis; each new state as the state input it feeds
                axes.update(zip(outputs, (0, *family.stream_axes[1 : len(outputs)]), strict=True))
                torch.onnx.export(
                    model,
                    args,
                    str(path),
                    input_names=list(inputs),
                    output_names=list(outputs),
                    dynamic_axes={name: {axis: "streams"} for name, axis in axes.items()},
                    dynamo=False,
                    verbose=False,
                )
    finally:
        onnx_log.setLevel(level)
    return path


def _has_torchscript_exporter() -> bool:
    """Whether this torch still exports through TorchScript (``torch.onnx.export(..., dynamo=False)``)."""
    import inspect

    return "dynamo" in inspect.signature(torch.onnx.export).parameters and hasattr(torch.onnx, "utils")


def run_onnx(path: str | Path, bundle: ModelBundle, samples: np.ndarray) -> np.ndarray:
    """Run an exported model over a ``(T, C)`` log of one stream with onnxruntime: ``(T, K)``."""
    import onnxruntime as ort

    family = bundle.stage2_family()
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    inputs, outputs = family.onnx_inputs, family.onnx_outputs
    feed = family.zero_state(bundle, 1)
    out = np.empty((len(samples), len(bundle.classes)), np.float32)
    for t, x in enumerate(np.asarray(samples, np.float32)):
        probs, *state = session.run(list(outputs), {"x": x[None], **feed})
        feed = dict(zip(inputs[1:], state, strict=False))  # each state output feeds its input back
        feed.update({name: np.ones((1, 1), np.float32) for name in family.after_first})
        out[t] = probs[0]
    return out


def check_onnx(path: str | Path, bundle: ModelBundle, samples: np.ndarray) -> float:
    """Largest absolute difference between ONNX Runtime and the streaming runtime over ``samples``."""
    ours = StreamingClassifier(bundle).run(samples)
    return float(np.abs(run_onnx(path, bundle, samples) - ours).max())
