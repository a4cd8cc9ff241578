"""A third model family written the way ``docs/architecture.md`` tells a newcomer to: a logistic regression on the
default family's spectral frames (``--model logreg``). It lives in the tests and is registered only inside
:func:`registered`, so that the tests show the registry's claim: a family is one room and one line.

In the product the room would be ``training/spectral_logreg/``; here its modules are one namespace, ``ROOM``,
put where ``training.registry.family`` looks for ``training.spectral_logreg``.
"""

from __future__ import annotations

import contextlib
import sys
import types
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import pytest
import torch
from torch import nn
from torch.nn import functional as F

import training
from training import (
    ClassifierFit,
    Family,
    SpectralSteps,
    WindowFitConfig,
    classification_metrics,
    family,
    fold_indices,
    never,
)
from training.spectral_cnn import WindowStepModel, frame_rows

ROOM = "spectral_logreg"
KIND = "logreg"


@dataclass(frozen=True)
class LogregConfig:
    """Sizes of the logistic regression over a step's last ``window`` frames."""

    n_features: int
    n_classes: int
    window: int = 7
    kind: str = KIND

    @property
    def frame_width(self) -> int:
        return self.n_features // self.window


class LogregClassifier(nn.Module):
    """Standardise each frame, one linear layer over the stacked frames."""

    def __init__(self, config: LogregConfig) -> None:
        super().__init__()
        self.config = config
        self.register_buffer("in_mean", torch.zeros(config.frame_width))
        self.register_buffer("in_scale", torch.ones(config.frame_width))
        self.linear = nn.Linear(config.n_features, config.n_classes)

    def logits(self, windows: torch.Tensor) -> torch.Tensor:
        """``windows (N, W·F)`` -> ``logits (N, K)``."""
        w = self.config.window
        return self.linear((windows - self.in_mean.repeat(w)) * self.in_scale.repeat(w))

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, W·F)`` -> ``logits (B, T, K)``; no state."""
        return self.logits(features.flatten(0, 1)).unflatten(0, features.shape[:2]), None


def fit_logreg(
    features: Sequence[SpectralSteps],
    segments: Sequence[tuple[int, int, int, int]],
    classes: Sequence[str],
    *,
    config: WindowFitConfig,
    stretches: Sequence = (),
    progress=None,
    cancel=never,
) -> ClassifierFit:
    """k fold models, each trained with Adam on one row per frame of the segments outside its fold."""
    rows = [frame_rows(features[i], a, b) for i, a, b, _ in segments]  # (n_i, W·F) each
    folds = fold_indices([s[3] for s in segments], config.k_folds, config.seed)
    frames = np.concatenate([np.asarray(f.frames, np.float32) for f in features])  # (N, F)
    mean, std = frames.mean(0), np.where(frames.std(0) > 1e-8, frames.std(0), 1.0)
    models, true, pred = [], [], []
    for train_idx, val_idx in folds:
        torch.manual_seed(config.seed)
        model = LogregClassifier(LogregConfig(features[0].shape[1], len(classes), features[0].config.window))
        model.in_mean.copy_(torch.from_numpy(mean))
        model.in_scale.copy_(torch.from_numpy(1.0 / std))
        x = torch.from_numpy(np.concatenate([rows[i] for i in train_idx]))
        y = torch.from_numpy(np.concatenate([np.full(len(rows[i]), segments[i][3]) for i in train_idx]))
        opt = torch.optim.Adam(model.parameters(), lr=0.05)
        for _ in range(150):
            opt.zero_grad()
            F.cross_entropy(model.logits(x), y).backward()
            opt.step()
        models.append(model.eval())
        with torch.inference_mode():
            for i in val_idx:
                true.append(np.full(len(rows[i]), segments[i][3]))
                pred.append(model.logits(torch.from_numpy(rows[i])).argmax(1).numpy())
    metrics = classification_metrics(np.concatenate(true), np.concatenate(pred), classes)
    metrics["n_segments"] = len(segments)
    return ClassifierFit(models, metrics, [[] for _ in models], [v.tolist() for _, v in folds])


class TorchStep:
    """The streaming step: the ONNX module stepped with its state, within 1e-4 of the offline pass (its spectra are
    products with cosine and sine tables). A real room would write it in NumPy, as the default family does."""

    def __init__(self, bundle, *, streams: int, precision: str = "float32") -> None:
        self.model, self.bundle, self.streams = WindowStepModel(bundle).eval(), bundle, streams
        self.reset()

    def reset(self) -> None:
        zero = family("default").zero_state(self.bundle, self.streams)  # the same state as the default's step
        self.state = [torch.from_numpy(v) for v in zero.values()]

    @torch.inference_mode()
    def __call__(self, x: np.ndarray) -> np.ndarray:
        probs, *self.state = self.model(torch.from_numpy(np.array(x, np.float32)), *self.state)
        return probs.numpy()


def _zero_state(bundle, streams: int) -> dict[str, np.ndarray]:
    return family("default").zero_state(bundle, streams)


FAMILY = Family(
    name="logreg",
    summary="a logistic regression on the last few short-time spectral frames",
    kind=KIND,
    stage2_inputs="frames",
    new_classifier=lambda cfg: LogregClassifier(LogregConfig(**cfg)),
    stream_step=TorchStep,
    precisions=("float32",),
    step_module=WindowStepModel,
    onnx_inputs=family("default").onnx_inputs,
    onnx_outputs=family("default").onnx_outputs,
    stream_axes=family("default").stream_axes,
    zero_state=_zero_state,
    describe=lambda bundle: f"Logreg family: a logistic regression over {bundle.spectral.window} spectral frames.",
    onnx_usage=lambda bundle: "`classifier_stream.onnx` is the same step as the default family's.",
    fit=fit_logreg,
    stage1="next-frame",  # the default family's stage 1, whose frames it reads
)


@contextlib.contextmanager
def registered() -> Iterator[None]:
    """The family in the registry: its room where ``family()`` imports it from, one line in ``FAMILY_ROOMS``."""
    room = types.ModuleType(f"training.{ROOM}")
    room.FAMILY = FAMILY
    with pytest.MonkeyPatch.context() as mp:
        mp.setitem(sys.modules, f"training.{ROOM}", room)
        mp.setitem(training.FAMILY_ROOMS, "logreg", ROOM)
        yield
