"""A trained model as files: JSON config + safetensors weights, rebuilt from the config on load (no pickle)."""

from __future__ import annotations

import json
import os
import shutil
import uuid
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import load_file, save_file
from torch import nn

from ..normalizer import Normalizer
from ..paper_lstm import FeatureMode, Predictor, PredictorConfig
from ..registry import Family, family_of_kind
from ..spectral_cnn import FRAME_PREDICTOR_KIND, DriftReference, FramePredictor, FramePredictorConfig, SpectralConfig
from ..training_errors import BundleError
from .bundle_files import (
    BUNDLE_SCHEMA,
    CLASSIFIER_FILE,
    CONFIG_FILE,
    DRIFT_FILE,
    PREDICTOR_FILE,
    check_finite,
    classifier_kind,
    drift_of,
    read_config,
    spectral_of,
)


@dataclass
class ModelBundle:
    """Stage 1 (always) and the stage-2 ensemble (once trained), with what is needed to use them.

    Attributes:
        predictor: The frozen stage-1 model: the paper family's LSTM predictor of the raw samples, or the default
            family's predictor of the next spectral frame (``stage1_kind``; bundles of the default family saved
            before it hold the LSTM).
        normalizer: Input normalisation of the raw samples (stage 1's and the front end's).
        channels: Names of the input channels, in order.
        rate_hz: Sample rate the model was trained at.
        classifiers: The k fold models of the family's stage 2 (empty for a predictor-only bundle).
        classes: Terrain names, in the order of the classifier outputs.
        feature_mode: What stage 1 hands stage 2.
        metrics: Out-of-fold metrics of the classifier.
        info: Free-form description: training data summary, versions, dates.
        spectral: The default family's front end (``feature_mode == "spectral"``, and the frames a next-frame
            predictor reads); ``None`` for the paper family.
        drift: What the drift score compares a step with (the default family's, from the labelled frames); ``None``
            for the paper family and bundles trained before it existed.
    """

    predictor: Predictor | FramePredictor
    normalizer: Normalizer
    channels: tuple[str, ...]
    rate_hz: float
    classifiers: list[nn.Module] = field(default_factory=list)
    classes: tuple[str, ...] = ()
    feature_mode: FeatureMode = "hidden"
    metrics: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    spectral: SpectralConfig | None = None
    drift: DriftReference | None = None

    @property
    def stage1_kind(self) -> str:
        """``"lstm"`` (the paper's predictor of the next sample) or ``"next-frame"`` (of the next spectral frame)."""
        return FRAME_PREDICTOR_KIND if isinstance(self.predictor, FramePredictor) else "lstm"

    @property
    def family(self) -> str:
        """The name of the model family whose classifier this is; for a predictor-only bundle, the family whose
        stage 1 it is (``"default"`` for the next-frame predictor, ``"paper"`` for the LSTM)."""
        if self.classifiers:
            return self.stage2_family().name
        return "default" if self.stage1_kind == FRAME_PREDICTOR_KIND else "paper"

    def stage2_family(self) -> Family:
        """The registry's entry for the family of the classifier (found by its config's ``kind``)."""
        if not self.classifiers:
            raise BundleError("the bundle has no classifier: train stage 2 first")
        return family_of_kind(classifier_kind(asdict(self.classifiers[0].config)))

    def config(self) -> dict:
        """Everything but the weights, as JSON-able data."""
        return {
            "schema": BUNDLE_SCHEMA,
            "predictor": asdict(self.predictor.config),
            "classifier": asdict(self.classifiers[0].config) if self.classifiers else None,
            "n_folds": len(self.classifiers),
            "normalizer": self.normalizer.to_dict(),
            "channels": list(self.channels),
            "rate_hz": self.rate_hz,
            "classes": list(self.classes),
            "feature_mode": self.feature_mode,
            "metrics": self.metrics,
            "info": self.info,
            "spectral": None if self.spectral is None else self.spectral.to_dict(),
            "drift": None if self.drift is None else self.drift.settings(),
        }


def _predictor(cfg: dict) -> Predictor | FramePredictor:
    """An untrained stage-1 module of the kind and sizes ``cfg`` (a bundle's ``predictor`` entry) names: the LSTM's
    config has no ``kind`` (bundles saved before the frame predictor)."""
    if cfg.get("kind", "lstm") == FRAME_PREDICTOR_KIND:
        return FramePredictor(FramePredictorConfig(**cfg))
    return Predictor(PredictorConfig(**cfg))


def _classifier(cfg: dict, directory: Path) -> nn.Module:
    """An untrained stage-2 module of the family and sizes ``cfg`` (a bundle's ``classifier`` entry) names."""
    return family_of_kind(classifier_kind(cfg), where=str(directory)).new_classifier(cfg)


def save_bundle(bundle: ModelBundle, directory: str | Path) -> Path:
    """Write a bundle to ``directory``, which must not exist: written under a temporary name, renamed when whole.

    Returns:
        ``directory``.
    """
    directory = Path(directory)
    if directory.exists():
        raise FileExistsError(f"{directory} exists already")
    tmp = directory.with_name(f".tmp-{directory.name}-{uuid.uuid4().hex[:8]}")
    tmp.mkdir(parents=True)
    try:
        save_file({k: v.contiguous() for k, v in bundle.predictor.state_dict().items()}, tmp / PREDICTOR_FILE)
        if bundle.classifiers:
            weights = {
                f"fold{i}.{k}": v.contiguous()
                for i, m in enumerate(bundle.classifiers)
                for k, v in m.state_dict().items()
            }
            save_file(weights, tmp / CLASSIFIER_FILE)
        if bundle.drift is not None:
            save_file({k: torch.from_numpy(v) for k, v in bundle.drift.arrays().items()}, tmp / DRIFT_FILE)
        (tmp / CONFIG_FILE).write_text(json.dumps(bundle.config(), indent=1))
        for f in tmp.iterdir():
            with open(f, "rb") as fh:
                os.fsync(fh.fileno())
        os.replace(tmp, directory)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return directory


def load_bundle(directory: str | Path) -> ModelBundle:
    """Rebuild a bundle from its config and weights.

    Raises:
        BundleError: Missing or damaged files, or a newer schema.
    """
    directory = Path(directory)
    cfg = read_config(directory)
    if cfg.get("classifier"):
        family_of_kind(classifier_kind(cfg["classifier"]), where=str(directory))  # unknown or retired: refused here
    try:
        _check_shapes(directory, cfg)  # before any module is built: model.json's sizes allocate memory
        spectral = spectral_of(directory, cfg)
        predictor = _predictor(cfg["predictor"])
        predictor.load_state_dict(load_file(directory / PREDICTOR_FILE))
        classifiers = []
        if cfg.get("classifier"):
            weights = load_file(directory / CLASSIFIER_FILE)
            for i in range(int(cfg["n_folds"])):
                model = _classifier(cfg["classifier"], directory)
                prefix = f"fold{i}."
                state = {k[len(prefix) :]: v for k, v in weights.items() if k.startswith(prefix)}
                for key, value in model.state_dict().items():
                    if key.startswith("in_"):  # bundles from before the input standardisation: identity
                        state.setdefault(key, value)
                model.load_state_dict(state)
                classifiers.append(model.eval())
        drift = drift_of(directory, cfg)
        normalizer = Normalizer.from_dict(cfg["normalizer"])
    except (OSError, KeyError, TypeError, RuntimeError, ValueError, SafetensorError) as exc:
        raise BundleError(f"{directory}: damaged model bundle ({type(exc).__name__}: {exc})") from None
    weights = [(f"{PREDICTOR_FILE}: {k}", v.numpy()) for k, v in predictor.state_dict().items()]
    for i, model in enumerate(classifiers):
        weights += [(f"{CLASSIFIER_FILE}: fold{i}.{k}", v.numpy()) for k, v in model.state_dict().items()]
    check_finite(directory, weights, drift, normalizer)
    return ModelBundle(
        predictor=predictor.eval(),
        normalizer=normalizer,
        channels=tuple(cfg["channels"]),
        rate_hz=float(cfg["rate_hz"]),
        classifiers=classifiers,
        classes=tuple(cfg["classes"]),
        feature_mode=cfg["feature_mode"],
        metrics=cfg.get("metrics", {}),
        info=cfg.get("info", {}),
        spectral=spectral,
        drift=drift,
    )


def _header_shapes(path: Path) -> dict[str, tuple[int, ...]]:
    """Tensor shapes from a safetensors file's header (read without loading a weight)."""
    with safe_open(path, framework="pt") as f:
        return {k: tuple(f.get_slice(k).get_shape()) for k in f.keys()}  # noqa: SIM118 (safe_open is no dict)


def _check_shapes(directory: Path, cfg: dict) -> None:
    """Refuse a bundle whose ``model.json`` sizes disagree with its weights' headers, before allocating anything.

    The modules are built on PyTorch's meta device (shapes only, no memory), so a tampered ``hidden: 10**9`` costs
    nothing and is refused instead of allocating hundreds of GB.
    """

    def compare(expected: dict, found: dict[str, tuple[int, ...]], prefix: str = "") -> None:
        for key, value in expected.items():
            if key.startswith("in_") and prefix + key not in found:
                continue  # bundles from before the input standardisation lack it: loaded as identity
            if found.get(prefix + key) != tuple(value.shape):
                raise BundleError(
                    f"{directory}: model.json does not match the weights ({prefix}{key}: {tuple(value.shape)} "
                    f"expected, {found.get(prefix + key, 'missing')} stored); the bundle was changed or damaged"
                )

    with torch.device("meta"):
        try:
            predictor = _predictor(cfg["predictor"])
        except RuntimeError as exc:  # sizes past what any tensor can hold
            raise BundleError(f"{directory}: model.json's predictor sizes are impossible ({exc})") from None
        compare(predictor.state_dict(), _header_shapes(directory / PREDICTOR_FILE))
        if cfg.get("classifier"):
            header = _header_shapes(directory / CLASSIFIER_FILE)
            folds = {k.split(".", 1)[0] for k in header}
            if int(cfg["n_folds"]) != len(folds):
                raise BundleError(
                    f"{directory}: model.json names {cfg['n_folds']} ensemble members, the weights hold {len(folds)}"
                )
            fold = _classifier(cfg["classifier"], directory).state_dict()
            for i in range(len(folds)):
                compare(fold, header, f"fold{i}.")


def parameter_count(bundle: ModelBundle) -> int:
    return sum(p.numel() for m in [bundle.predictor, *bundle.classifiers] for p in m.parameters())
