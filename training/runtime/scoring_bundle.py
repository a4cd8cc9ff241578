"""A default-family bundle read for scoring log files, without PyTorch: its settings, its drift reference and its
members' weights as arrays (:class:`~training.spectral_cnn.frame_numpy.NumpyMembers`).

``workbench classify`` of a ten-minute run spent 3.5 of its 7.8 s importing PyTorch. A bundle of the default family
needs none of it to score: its front end and its drift are NumPy already, and its members are some 30 k weights each.
The files are checked as :func:`.bundle.load_bundle` checks them (the same one-line refusals: a missing or damaged
file, a schema from a newer workbench, sizes that disagree with the weights before anything is allocated, a weight
that is not finite). A bundle of another family, or one without a classifier, is not read here: the caller loads it
with :func:`.bundle.load_bundle`, which also says what is wrong with a kind no family knows.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from safetensors import SafetensorError, safe_open
from safetensors.numpy import load_file

from ..normalizer import Normalizer
from ..spectral_cnn import WINDOW_KIND, DriftReference, NumpyMembers, SpectralConfig
from ..training_errors import BundleError
from .bundle_files import CLASSIFIER_FILE, check_finite, classifier_kind, drift_of, read_config, spectral_of


@dataclass(frozen=True)
class ScoringBundle:
    """What scoring log files with a default-family bundle needs, as arrays.

    Attributes:
        members: The stage-2 ensemble.
        normalizer: Input normalisation of the raw samples.
        spectral: The front end.
        channels: Names of the input channels, in order.
        rate_hz: Sample rate the model was trained at.
        classes: Terrain names, in the order of the probabilities.
        metrics: The model card's metrics.
        drift: The drift reference, where the bundle has one.
    """

    members: NumpyMembers
    normalizer: Normalizer
    spectral: SpectralConfig
    channels: tuple[str, ...]
    rate_hz: float
    classes: tuple[str, ...]
    metrics: dict = field(default_factory=dict)
    drift: DriftReference | None = None


def load_scoring_bundle(directory: str | Path) -> ScoringBundle | None:
    """The bundle in ``directory`` as arrays when its classifier is the default family's; ``None`` otherwise (no
    classifier, another family, a kind no family knows: :func:`.bundle.load_bundle` reads or refuses those).

    Raises:
        BundleError: Missing or damaged files, a newer schema, sizes that disagree with the weights.
    """
    directory = Path(directory)
    cfg = read_config(directory)
    if not isinstance(cfg.get("classifier"), dict) or classifier_kind(cfg["classifier"]) != WINDOW_KIND:
        return None
    try:
        states = _member_states(directory, cfg)
        spectral = spectral_of(directory, cfg)
        drift = drift_of(directory, cfg)
        normalizer = Normalizer.from_dict(cfg["normalizer"])
        if spectral is None:
            raise BundleError(f"{directory}: model.json has a default-family classifier but no spectral front end")
        members = NumpyMembers(states, window=int(cfg["classifier"]["window"]))
        channels, classes = tuple(cfg["channels"]), tuple(cfg["classes"])
        if len(classes) != members.n_classes or len(channels) != len(normalizer.mean):
            raise ValueError("the classes or channels do not match the weights")
        bundle = ScoringBundle(
            members, normalizer, spectral, channels, float(cfg["rate_hz"]), classes, cfg.get("metrics", {}), drift
        )
    except (OSError, KeyError, TypeError, ValueError, SafetensorError) as exc:
        raise BundleError(f"{directory}: damaged model bundle ({type(exc).__name__}: {exc})") from None
    weights = [(f"{CLASSIFIER_FILE}: fold{i}.{k}", v) for i, s in enumerate(states) for k, v in s.items()]
    check_finite(directory, weights, drift, normalizer)
    return bundle


def _member_states(directory: Path, cfg: dict) -> list[dict[str, np.ndarray]]:
    """Each member's weights, their shapes checked against ``model.json`` from the file's header before any is read
    (a tampered ``hidden: 10**9`` is refused, not allocated)."""
    c = cfg["classifier"]
    window = int(c["window"])
    sizes = {
        "frame_width": int(c["n_features"]) // window,
        "hidden": int(c["hidden"]),
        "n_classes": int(c["n_classes"]),
    }
    expected = NumpyMembers.weight_shapes(**sizes)
    optional = {"in_mean", "in_scale"}  # bundles saved before the input standardisation lack them: the identity
    path = directory / CLASSIFIER_FILE
    with safe_open(path, framework="np") as file:
        shapes = {name: tuple(file.get_slice(name).get_shape()) for name in file.keys()}  # noqa: SIM118 (no dict)
    folds = {name.split(".", 1)[0] for name in shapes}
    if int(cfg["n_folds"]) != len(folds) or folds != {f"fold{i}" for i in range(len(folds))}:
        raise BundleError(
            f"{directory}: model.json names {cfg['n_folds']} ensemble members, the weights hold {len(folds)}"
        )
    for fold in sorted(folds):
        names = {n.split(".", 1)[1] for n in shapes if n.startswith(f"{fold}.")}
        if not set(expected) - optional <= names <= set(expected):
            raise ValueError(f"{fold} holds {sorted(names)}, not the window classifier's weights")
        for name in names:
            if shapes[f"{fold}.{name}"] != expected[name]:
                raise BundleError(
                    f"{directory}: model.json does not match the weights ({fold}.{name}: {expected[name]} expected, "
                    f"{shapes[f'{fold}.{name}']} stored); the bundle was changed or damaged"
                )
    weights = load_file(path)
    return [{n.split(".", 1)[1]: v for n, v in weights.items() if n.startswith(f"fold{i}.")} for i in range(len(folds))]
