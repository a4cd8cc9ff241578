"""The registry: a family is found by name and by the kind its bundle saved, and a third family (one room, one
registry line) runs through the bundle, the offline pass, the streaming runtime and the ONNX export unchanged."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from training import (
    BundleError,
    ModelBundle,
    Normalizer,
    Predictor,
    PredictorConfig,
    SpectralConfig,
    SpectralSteps,
    StreamingClassifier,
    WindowFitConfig,
    check_onnx,
    export_onnx,
    family,
    family_names,
    load_bundle,
    log_frames,
    run_classifiers,
    save_bundle,
)

from .third_family import FAMILY as LOGREG
from .third_family import registered

RATE = 50.0


def _log(terrain: int, n: int, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(n) / RATE
    fast = np.sin(2 * np.pi * (5.0, 14.0)[terrain] * t) + 0.3 * rng.normal(size=n)
    return np.column_stack([fast, rng.normal(size=n)]).astype(np.float32)


def test_families_are_found_by_name_and_unknown_ones_are_refused() -> None:
    assert family_names() == ("default", "minirocket", "paper")
    assert family("default").stage2_inputs == "frames" and family("paper").stage2_inputs == "stage1"
    assert family("minirocket").stage2_inputs == "windows" and family("minirocket").stage1 == "next-frame"
    with pytest.raises(KeyError, match="unknown model family 'logreg'; choose one of default, minirocket, paper"):
        family("logreg")


def test_a_third_family_is_one_room_and_one_registry_line(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    logs = [_log(k, 1200, rng) for k in (0, 1, 0, 1)]
    norm = Normalizer.fit(logs)
    front = SpectralConfig.for_log(logs[0], RATE)
    feats = [SpectralSteps(log_frames(x, front, transform=norm), len(x), front) for x in logs]
    segments = [(i, 200, 1000, k) for i, k in enumerate((0, 1, 0, 1))]
    with registered():
        assert family_names() == ("default", "logreg", "minirocket", "paper")
        fit = family("logreg").fit(feats, segments, ("grass", "ice"), config=WindowFitConfig(k_folds=2))
        assert fit.metrics["accuracy"] > 0.9  # the two terrains differ in their spectra
        bundle = ModelBundle(
            Predictor(PredictorConfig(2, 4)), norm, ("fast", "noise"), RATE, fit.models, ("grass", "ice"),
            "spectral", fit.metrics, {}, front,
        )  # fmt: skip
        assert bundle.family == "logreg"
        again = load_bundle(save_bundle(bundle, tmp_path / "b"))  # rebuilt from its config's kind
        assert again.family == "logreg" and type(again.classifiers[0]) is type(fit.models[0])
        offline = run_classifiers(again.classifiers, [feats[1]])[0].mean(0)  # (T, K)
        streamed = StreamingClassifier(again).run(logs[1])
        np.testing.assert_allclose(streamed, offline, atol=1e-5)
        assert check_onnx(export_onnx(again, tmp_path / "step.onnx"), again, logs[1][:150]) < 1e-5
        assert "logistic regression" in LOGREG.describe(again)
    with pytest.raises(BundleError, match="kind 'logreg', which no model family of this workbench knows"):
        load_bundle(tmp_path / "b")  # the family gone: refused in one line, not a crash
