"""The default family as the registry sees it: its modules, its streaming step, its ONNX step and its model card."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..registry import Family
from .frame_predictor import FramePredictor
from .kinds import OLD_WINDOW_KINDS, WINDOW_KIND
from .window_classifier import WindowClassifier, WindowClassifierConfig
from .window_step import INPUTS, OUTPUTS, WindowStep, WindowStepModel, zero_state

if TYPE_CHECKING:
    from ..fitting import ClassifierFit
    from ..runtime import ModelBundle


def _classifier(cfg: dict) -> WindowClassifier:
    return WindowClassifier(WindowClassifierConfig(**cfg))


def _stream_step(bundle: ModelBundle, *, streams: int, precision: str) -> WindowStep:
    return WindowStep(bundle, streams=streams)


def _stage1(bundle: ModelBundle) -> str:
    p = bundle.predictor
    if isinstance(p, FramePredictor):
        return (
            f"causal convolutions of {p.config.hidden} channels predicting each short-time frame from the "
            f"{p.context} before it"
        )
    return f"an LSTM of {p.config.hidden} units predicting each sample"  # sessions trained before the frame predictor


def _describe(bundle: ModelBundle) -> str:
    f, c, members = bundle.spectral, bundle.classifiers[0].config, len(bundle.classifiers)
    assert f is not None  # a default-family bundle always holds its front end (checked on load)
    return (
        f"Default family: short-time spectra and a small convolutional network. A predictor (stage 1, "
        f"{_stage1(bundle)}) trained without labels on all logs, then frozen; it draws the surprise highlights. "
        f"The classifier (stage 2) reads the last {f.window} short-time frames ({f.frame} "
        f"samples every {f.hop}): log power spectra of {len(f.fast)} fast channels and the level and range of "
        f"{len(f.slow)} slow ones, {c.frame_width} features a frame; a 1x1 convolution and a 3-frame convolution of "
        f"{c.hidden} channels, their mean and spread over the frames, a linear layer. Fitted on the labelled "
        f"segments and, by self-training, on unlabelled stretches whose frames agree; an ensemble of {members} "
        "fold models."
    )


def _fit(*args: Any, **kwargs: Any) -> ClassifierFit:
    from .fit_window import fit_window_classifier  # on first use: a bundle is loaded without the fits

    return fit_window_classifier(*args, **kwargs)


def _fine_tune(*args: Any, **kwargs: Any) -> ClassifierFit:
    from .window_finetune import fine_tune_window_classifier

    return fine_tune_window_classifier(*args, **kwargs)


def _onnx_usage(bundle: ModelBundle) -> str:
    return (
        "`classifier_stream.onnx` is the same step: inputs `x (B, C)`, `ring (B, L, C)`, `count (B, 1)`, "
        "`frames (B, W, F)`, `n_frames (B, 1)` (all zeros at a stream's start); outputs `probs (B, K)` and the "
        "new `ring, count, frames, n_frames`, fed back at the next sample."
    )


FAMILY = Family(
    name="default",
    summary="short-time log spectra of the signals and a small convolutional network over the last few of them, "
    "fitted on the labels and, by self-training, on unlabelled stretches",
    kind=WINDOW_KIND,
    stage2_inputs="frames",
    new_classifier=_classifier,
    stream_step=_stream_step,
    precisions=("float32",),  # a frame's products every hop: bfloat16 would change them for little speed
    step_module=WindowStepModel,
    onnx_inputs=INPUTS,
    onnx_outputs=OUTPUTS,
    stream_axes=(0,) * len(INPUTS),
    zero_state=zero_state,
    describe=_describe,
    onnx_usage=_onnx_usage,
    fit=_fit,
    fine_tune=_fine_tune,
    self_training=True,
    keeps_starts=True,
    stage1="next-frame",
    devices=("cpu", "cuda"),
    retired_kinds={
        k: "a default-family classifier from an older workbench (a linear model on window summaries); train it "
        "again (workbench train SESSION): labels are kept"
        for k in OLD_WINDOW_KINDS
    },
)
