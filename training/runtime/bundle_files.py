"""A bundle's files read without PyTorch: ``model.json`` and the checks every loader makes of it, the drift
reference's arrays, and the refusal of weights that are not finite. :mod:`.bundle` rebuilds the modules from them;
:mod:`.scoring_bundle` keeps the default family's weights as arrays."""

from __future__ import annotations

import json
import stat
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from safetensors.numpy import load_file

from ..normalizer import Normalizer
from ..spectral_cnn import FRAME_PREDICTOR_KIND, DriftReference, SpectralConfig
from ..training_errors import BundleError

BUNDLE_SCHEMA = 1
CONFIG_FILE = "model.json"
PREDICTOR_FILE = "predictor.safetensors"
CLASSIFIER_FILE = "classifier.safetensors"
DRIFT_FILE = "drift.safetensors"
MAX_CONFIG_BYTES = 32 << 20
"""``model.json`` on disk: sizes, class names and the model card's metrics are kilobytes (a bundle trained on 72 runs:
about 100 KB); a larger one is damage or tampering, refused before it is read (a 300 MB one took 1 GB to parse)."""


def classifier_kind(cfg: dict) -> str:
    """The family ``kind`` a classifier config names: bundles saved before the paper family named its own lack it."""
    return str(cfg.get("kind", "lstm"))


def frame_kind(cfg: dict) -> bool:
    """``model.json``'s predictor is the next-frame predictor."""
    return isinstance(cfg.get("predictor"), dict) and cfg["predictor"].get("kind") == FRAME_PREDICTOR_KIND


def regular_file(path: Path, *, missing_ok: bool = False) -> int:
    """The size of ``path``, refused unless it is a regular file (a FIFO, a device or a folder named as a weights
    file is damage or tampering: opening a FIFO waits for a writer for ever). Returns -1 for a missing file when
    ``missing_ok``."""
    try:
        st = path.stat()
    except FileNotFoundError:
        if missing_ok:
            return -1
        raise BundleError(f"{path.parent}: not a model bundle ({path.name} is missing)") from None
    except OSError as exc:
        raise BundleError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise BundleError(f"{path}: not a regular file; a model bundle holds plain files only")
    return st.st_size


def read_config(directory: Path) -> dict:
    """``model.json``, refused in one line when it is not a plain file, too large, nested too deep or not JSON; and
    the weights files refused when they are not plain files, and a schema newer than this workbench's."""
    path = directory / CONFIG_FILE
    if (size := regular_file(path)) > MAX_CONFIG_BYTES:
        raise BundleError(f"{path}: {size:,} bytes; a model.json is at most {MAX_CONFIG_BYTES:,} (damaged or changed)")
    try:
        cfg = json.loads(path.read_text(encoding="utf-8"))
    except RecursionError:
        raise BundleError(f"{path}: JSON nested deeper than the parser allows; not a model bundle") from None
    except (OSError, ValueError) as exc:
        raise BundleError(f"{directory}: not a model bundle ({type(exc).__name__}: {exc})") from None
    if not isinstance(cfg, dict):
        raise BundleError(f"{path}: not a model bundle (its top level is no JSON object)")
    for name in (PREDICTOR_FILE, CLASSIFIER_FILE, DRIFT_FILE):
        regular_file(directory / name, missing_ok=True)  # a FIFO would block its reader for ever
    if int(cfg.get("schema", 0)) > BUNDLE_SCHEMA:
        raise BundleError(f"{directory}: bundle schema {cfg['schema']} is newer than this workbench ({BUNDLE_SCHEMA})")
    return cfg


def check_finite(
    directory: Path,
    weights: Iterable[tuple[str, np.ndarray]],
    drift: DriftReference | None,
    normalizer: Normalizer,
) -> None:
    """Refuse weights holding NaN or inf: every probability would be NaN, and NaN's argmax reads as the first
    terrain (measured: a bundle of NaN weights classified every row as the first class, exit 0); and a normalizer
    scale not above 0. ``weights``: the modules' arrays, each named as the message shows it
    (``"classifier.safetensors: fold0.mix.weight"``); the drift's and the normalizer's are named here."""
    arrays = [*weights, *((f"{DRIFT_FILE}: {k}", v) for k, v in (drift.arrays() if drift is not None else {}).items())]
    arrays += [
        ("model.json: the normalizer's mean", normalizer.mean),
        ("model.json: the normalizer's std", normalizer.std),
    ]
    for name, value in arrays:
        value = np.asarray(value)
        if np.issubdtype(value.dtype, np.floating) and not bool(np.isfinite(value).all()):
            bad = int((~np.isfinite(value)).sum())
            raise BundleError(
                f"{directory}: {name} holds {bad:,} NaN or infinite value(s); the bundle is damaged (export it again)"
            )
    if not bool((normalizer.std > 0).all()):
        raise BundleError(f"{directory}: model.json's normalizer has a scale not above 0; the bundle is damaged")


def drift_of(directory: Path, cfg: dict) -> DriftReference | None:
    """The drift reference, when the bundle has one whose embeddings are as wide as its classifier's.

    Raises:
        ValueError: It does not match the classifier (the loaders name the bundle damaged).
    """
    if not cfg.get("drift") or not cfg.get("classifier"):
        return None
    drift = DriftReference.from_arrays(load_file(directory / DRIFT_FILE), cfg["drift"])
    width = 2 * int(cfg["classifier"].get("hidden", 0))
    frame = int(cfg["classifier"]["n_features"]) // int(cfg["classifier"].get("window", 1))
    fits = all(r.shape[1] == width for r in drift.references) and all(x.shape[1] == frame for x in drift.inputs)
    if int(cfg["drift"]["members"]) != int(cfg["n_folds"]) or not fits:
        raise ValueError("the drift reference does not match the classifier")
    return drift


def spectral_of(directory: Path, cfg: dict) -> SpectralConfig | None:
    """The front end of ``model.json``, refused when its sizes disagree with the channels and the classifier."""
    if not cfg.get("spectral"):
        if frame_kind(cfg):
            raise BundleError(f"{directory}: model.json has a next-frame predictor but no spectral front end")
        return None
    spectral = SpectralConfig.from_dict(cfg["spectral"])
    n = len(cfg["channels"])
    sane = (
        0 < spectral.hop <= spectral.frame <= 1 << 16
        and 0 < spectral.window <= 1 << 12
        and all(0 <= c < n for c in (*spectral.fast, *spectral.slow))
        and _reads_front_end(cfg.get("classifier"), spectral, n)
        and (not frame_kind(cfg) or cfg["predictor"]["n_features"] == spectral.width)
    )
    if not sane:
        raise BundleError(f"{directory}: model.json's spectral front end does not fit its channels and classifier")
    return spectral


def _reads_front_end(classifier: dict | None, spectral: SpectralConfig, channels: int) -> bool:
    """The classifier's inputs fit the bundle: a frames classifier's width is the front end's step, a windows
    classifier (MiniRocket, whose config has no ``n_features``) reads the bundle's channels."""
    if not classifier:
        return True
    if "n_features" in classifier:
        return classifier["n_features"] == spectral.step_width
    return int(classifier.get("channels", channels)) == channels
