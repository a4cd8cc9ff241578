"""Model families by name: each family is a room of ``training`` (a sub-package), and this table maps a name to it.

``workbench train --model NAME``, a saved bundle (its stage-2 config's ``kind``), the streaming runtime, the ONNX
export and the model card find a family here. A third family is a new room whose ``__init__`` exports a
:class:`Family` as ``FAMILY``, and one line in :data:`FAMILY_ROOMS`. Nothing here imports PyTorch: ``workbench --help``
lists the names without loading a room.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from .training_errors import BundleError

if TYPE_CHECKING:
    import numpy as np
    from torch import nn

# What a family's callables take as ``bundle`` is a ``training.ModelBundle``; it is not imported here because the
# bundle finds its family through this module (the hints say ``Any`` rather than make the two modules a circle).
Bundle = Any

FAMILY_ROOMS: dict[str, str] = {
    "default": "spectral_cnn",  # short-time log spectra and a small convolutional network, with self-training
    "paper": "paper_lstm",  # the paper's method: two stacked LSTMs (a predictor, then a classifier on its states)
    "minirocket": "minirocket",  # MiniRocket: fixed convolutions of the samples, a ridge head; the default stage 1
}
DEFAULT_FAMILY = "default"
# a classifier version saved before versions named their family was the paper family's (the only one then)
UNNAMED_FAMILY = "paper"


@dataclass(frozen=True)
class Family:
    """What a family's room gives the shared machinery (bundle, passes, stream, ONNX export, model card).

    Attributes:
        name: Its ``--model`` name (a key of :data:`FAMILY_ROOMS`).
        summary: What it is, in a sentence (``workbench train --help``, the model card).
        kind: The ``kind`` its stage-2 config carries in a bundle's ``model.json``.
        stage2_inputs: What the workbench computes for its stage 2 from a log: ``"frames"`` (the spectral front
            end's frames, cached per log), ``"windows"`` (the normalised samples themselves, a window per hop read
            on demand: ``RawSteps``) or ``"stage1"`` (the LSTM predictor's outputs, cached per log).
        new_classifier: An untrained stage-2 module from a bundle's classifier config (a dict of its fields).
        stream_step: ``(bundle, streams=, precision=)`` -> the NumPy runtime's step: called with ``(B, C)`` raw
            samples it returns ``(B, K)`` probabilities; ``reset()`` forgets every stream's past.
        precisions: What ``stream_step`` runs, the default first.
        step_module: The same step as an ``nn.Module`` whose state is explicit inputs and outputs: what the ONNX
            export traces.
        onnx_inputs: The step's inputs: ``x`` first, then its state.
        onnx_outputs: Its outputs: ``probs`` first, then the new state, in the order of the state inputs they feed.
        stream_axes: Per input, the axis that counts streams (dynamic in the ONNX graph).
        zero_state: ``(bundle, streams)`` -> the state inputs of a stream's first step.
        after_first: State inputs with no output that are set to ones after a stream's first step.
        describe: ``bundle`` -> the model card's sentences on what the bundle's models are.
        onnx_usage: ``bundle`` -> the model card's sentence on the exported step's inputs and outputs.
        fit: Its stage 2 from scratch, called by the workbench with the inputs ``stage2_inputs`` names: ``(features,
            segments, classes, *, config, progress, cancel, ...)`` -> ``ClassifierFit``. A ``"frames"`` or
            ``"windows"`` family takes ``SpectralSteps`` (``RawSteps``), a ``WindowFitConfig``, ``stretches``
            (unlabelled ``(log, start, stop)``, for ``self_training``) and, only when ``config.unit_agree`` is set,
            ``units``. A ``"stage1"`` family takes stage 1's features per log, a ``TrainConfig``, ``hidden``, and
            ``init`` (the active classifier's modules to start from, with ``warm_start``), ``new`` (the labels added
            since, trained on first) and ``pairs`` (consistency pairs, when ``config.consistency`` is set).
        fine_tune: The quick Retrain: ``(features, segments, classes, models, *, folds, new, steps, lr_scale,
            config, progress, cancel)`` -> ``ClassifierFit`` of the fold models fine-tuned on new labels; ``None``
            where the family has none (a ``warm_start`` family warm-starts inside ``fit``).
        self_training: A ``"frames"`` family whose ``fit`` also learns from the unlabelled stretches of every log
            (the workbench then finds them and passes ``stretches``).
        keeps_starts: A ``"frames"`` family whose ``fit`` takes ``starts``, a folder where it keeps the networks it
            trained on the labels alone and reads those a later fit would train again (the export's taught fit).
        warm_start: A ``"stage1"`` family whose ``fit`` starts from the active classifier's modules when they fit
            (same predictor, terrains and features): the workbench passes them as ``init``.
        retired_kinds: Kinds an older workbench saved for this family that no longer load, and what to do.
        stage1: Its stage 1: ``"lstm"`` (the paper's predictor of the next raw sample, whose outputs the paper's
            stage 2 reads) or ``"next-frame"`` (the default family's predictor of the next spectral frame, which
            draws the surprise highlight and the suggestions' embeddings; stage 2 reads the frames).
        devices: Where its fits and passes run: ``("cpu",)`` or ``("cpu", "cuda")``. ``--device cuda`` with a family
            that has no CUDA path is refused in one line (:func:`device_refusal`), never run on the CPU unsaid.
        cpu_only_why: Why it has no CUDA path, in a clause (the refusal's words).
    """

    name: str
    summary: str
    kind: str
    stage2_inputs: Literal["frames", "windows", "stage1"]
    new_classifier: Callable[[dict], nn.Module]
    stream_step: Callable[..., Any]
    precisions: tuple[str, ...]
    step_module: Callable[[Bundle], nn.Module]
    onnx_inputs: tuple[str, ...]
    onnx_outputs: tuple[str, ...]
    stream_axes: tuple[int, ...]
    zero_state: Callable[[Bundle, int], dict[str, np.ndarray]]
    describe: Callable[[Bundle], str]
    onnx_usage: Callable[[Bundle], str]
    fit: Callable[..., Any]
    fine_tune: Callable[..., Any] | None = None
    self_training: bool = False
    keeps_starts: bool = False
    warm_start: bool = False
    after_first: tuple[str, ...] = ()
    retired_kinds: Mapping[str, str] = field(default_factory=dict)
    stage1: Literal["lstm", "next-frame"] = "lstm"
    devices: tuple[str, ...] = ("cpu",)
    cpu_only_why: str = ""


def family_names() -> tuple[str, ...]:
    """Every family's ``--model`` name, the default first."""
    return (DEFAULT_FAMILY, *sorted(n for n in FAMILY_ROOMS if n != DEFAULT_FAMILY))


def recorded_family(config: Mapping[str, Any] | None) -> str:
    """The family a classifier version's config names (``model``): ``DEFAULT_FAMILY`` with no version, the paper
    family's for a version saved before versions named theirs."""
    return DEFAULT_FAMILY if config is None else str(config.get("model", UNNAMED_FAMILY))


def family(name: str) -> Family:
    """The family called ``name`` (its room is imported on first use).

    Raises:
        KeyError: No family has that name.
    """
    if name not in FAMILY_ROOMS:
        raise KeyError(f"unknown model family {name!r}; choose one of {', '.join(family_names())}")
    return importlib.import_module(f".{FAMILY_ROOMS[name]}", __package__).FAMILY


def family_of_kind(kind: str, *, where: str = "the bundle") -> Family:
    """The family whose stage-2 modules a bundle's config names by ``kind``.

    Raises:
        BundleError: A kind no family knows, or one an older workbench saved that is retired (with what to do).
    """
    for name in FAMILY_ROOMS:
        fam = family(name)
        if fam.kind == kind:
            return fam
        if kind in fam.retired_kinds:
            raise BundleError(f"{where}: {fam.retired_kinds[kind]}")
    raise BundleError(f"{where}: a classifier of kind {kind!r}, which no model family of this workbench knows")


def device_refusal(name: str, device: str) -> str | None:
    """The one line refusing ``--device DEVICE`` for family ``name``, or ``None`` when it runs there.

    Raises:
        KeyError: No family has that name.
    """
    fam = family(name)
    if device in fam.devices:
        return None
    gpu = [n for n in family_names() if device in family(n).devices]
    other = f"; --model {' or --model '.join(gpu)} trains on {device}" if gpu else ""
    why = f" ({fam.cpu_only_why})" if fam.cpu_only_why else ""
    return f"--device {device}: the {name} family trains and scores on the CPU only{why}{other}; or leave --device out"
