"""The MiniRocket family as the registry sees it: its modules, its streaming step, its ONNX step and its model card.

Its stage 1 is the default family's (the next-frame predictor, trained without labels on all logs: the surprise
highlight and the suggestions' embeddings); its stage 2 reads the normalised samples themselves (``RawSteps``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..registry import Family
from .rocket_classifier import ROCKET_KIND, RocketClassifier, RocketClassifierConfig
from .rocket_step import INPUTS, OUTPUTS, RocketStep, RocketStepModel, zero_state

if TYPE_CHECKING:
    from ..fitting import ClassifierFit
    from ..runtime import ModelBundle


def _classifier(cfg: dict) -> RocketClassifier:
    return RocketClassifier(RocketClassifierConfig(**cfg))


def _stream_step(bundle: ModelBundle, *, streams: int, precision: str) -> RocketStep:
    return RocketStep(bundle, streams=streams)


def _describe(bundle: ModelBundle) -> str:
    c: RocketClassifierConfig = bundle.classifiers[0].config
    seconds = c.length / bundle.rate_hz
    return (
        "MiniRocket family (Dempster et al., 2021, as aeon's MiniRocketClassifier). The default family's predictor "
        "(stage 1, trained without labels on all logs, then frozen) draws the surprise highlights. The classifier "
        f"(stage 2) reads the last {c.length} normalised samples ({seconds:.1f} s) of the {c.channels} channels "
        f"every {c.hop} samples: 84 fixed kernels of 9 taps at {len(c.dilations)} dilations, each on a random "
        f"subset of the channels, pooled into {c.rocket.features} proportions of positives above biases drawn from "
        f"all logs; a ridge classifier on them, one per fold ({len(bundle.classifiers)} in the ensemble), and one "
        "temperature for their probabilities."
    )


def _fit(*args: Any, **kwargs: Any) -> ClassifierFit:
    from .rocket_steps_fit import fit_rocket_steps  # on first use: a bundle is loaded without the fit

    return fit_rocket_steps(*args, **kwargs)


def _onnx_usage(bundle: ModelBundle) -> str:
    return (
        "`classifier_stream.onnx` is the same step: inputs `x (B, C)`, `ring (B, L, C)`, `count (B, 1)` (zeros at a "
        "stream's start) and `probs_in (B, K)` (at a stream's start, the probabilities of an empty window: "
        "`training.family('minirocket').zero_state(bundle, B)`); outputs `probs (B, K)` and the new `ring, count, "
        "probs_in`, fed back at the next sample. It classifies a stream only at its hops."
    )


FAMILY = Family(
    name="minirocket",
    summary="MiniRocket's fixed dilated convolutions of the signals themselves and a ridge classifier (the field's "
    "standard baseline), with the default family's stage 1",
    kind=ROCKET_KIND,
    stage2_inputs="windows",
    new_classifier=_classifier,
    stream_step=_stream_step,
    precisions=("float32",),
    step_module=RocketStepModel,
    onnx_inputs=INPUTS,
    onnx_outputs=OUTPUTS,
    stream_axes=(0,) * len(INPUTS),
    zero_state=zero_state,
    describe=_describe,
    onnx_usage=_onnx_usage,
    fit=_fit,
    stage1="next-frame",
    cpu_only_why="its stage 1 is the default family's; no CUDA path for its transform is built or tested yet",
)
