"""The paper family as the registry sees it: its modules, its streaming step, its ONNX step and its model card."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..registry import Family
from .fused_step import Bf16Step, FusedStep
from .lstm_config import ClassifierConfig
from .lstm_models import Classifier
from .lstm_step import INPUTS, OUTPUTS, STREAM_AXES, StepModel, zero_state

if TYPE_CHECKING:
    from ..fitting import ClassifierFit
    from ..runtime import ModelBundle


def _fit(*args: Any, **kwargs: Any) -> ClassifierFit:
    from .classifier_fit import fit_classifier  # on first use: a bundle is loaded without the fit

    return fit_classifier(*args, **kwargs)


def _classifier(cfg: dict) -> Classifier:
    return Classifier(ClassifierConfig(**cfg))


def _stream_step(bundle: ModelBundle, *, streams: int, precision: str) -> FusedStep | Bf16Step:
    return (FusedStep if precision == "float32" else Bf16Step)(bundle, streams=streams)


def _describe(bundle: ModelBundle) -> str:
    c, members = bundle.classifiers[0].config, len(bundle.classifiers)
    return (
        f"Paper family: two stacked LSTMs. A predictor (stage 1, an LSTM of {bundle.predictor.config.hidden} units) "
        f"trained without labels on all logs, then frozen; a classifier (stage 2, {c.hidden} units, dropout "
        f"{c.dropout:.0%}) on `{bundle.feature_mode}` features of stage 1, as an ensemble of {members} fold models."
    )


def _onnx_usage(bundle: ModelBundle) -> str:
    return (
        "`classifier_stream.onnx` is the same step: inputs `x (B, C)`, `h1, c1 (B, H1)`, `h2, c2 (M, B, H2)`, "
        "`prev (B, C)`, `started (B, 1)` (zeros at a stream's start, then ones); outputs `probs (B, K)` and the new "
        "states."
    )


FAMILY = Family(
    name="paper",
    summary="the paper's method: an LSTM predictor trained on all logs without labels, then an LSTM classifier "
    "on its hidden states and errors",
    kind="lstm",
    stage2_inputs="stage1",
    new_classifier=_classifier,
    stream_step=_stream_step,
    precisions=("float32", "bfloat16"),
    step_module=StepModel,
    onnx_inputs=INPUTS,
    onnx_outputs=OUTPUTS,
    stream_axes=STREAM_AXES,
    zero_state=zero_state,
    after_first=("started",),
    devices=("cpu", "cuda"),
    describe=_describe,
    onnx_usage=_onnx_usage,
    fit=_fit,
    warm_start=True,
)
