"""Bundles saved by an earlier version of the code load and score the same: one tiny bundle per model family,
written by ``tests/training/golden/make_golden.py`` before the model families moved into rooms of their own."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from training import (
    SpectralSteps,
    StreamingClassifier,
    check_onnx,
    export_onnx,
    load_bundle,
    log_frames,
    run_classifiers,
    run_onnx,
    run_predictor,
    save_bundle,
)

GOLDEN = Path(__file__).parent / "golden"
FAMILIES = ("paper", "default")


def offline(bundle, x: np.ndarray) -> np.ndarray:
    """The offline pass as the workbench scores a log: ``(T, K)`` ensemble mean."""
    if bundle.spectral is not None:
        features = SpectralSteps(log_frames(x, bundle.spectral, transform=bundle.normalizer), len(x), bundle.spectral)
    else:
        features = run_predictor(bundle.predictor, bundle.normalizer, [x])[0].lazy(bundle.feature_mode)
    return run_classifiers(bundle.classifiers, [features])[0].mean(0)


@pytest.mark.parametrize("name", FAMILIES)
def test_a_golden_bundle_loads_and_scores_as_when_it_was_saved(name: str, tmp_path: Path) -> None:
    x = np.load(GOLDEN / "log.npy")
    expected = np.load(GOLDEN / f"{name}.stream.npy")  # (T, K) the streaming runtime's output on the day
    bundle = load_bundle(GOLDEN / name)
    assert bundle.family == name and bundle.classes == ("grass", "gravel", "sand")
    assert bundle.info == {"golden": name}
    np.testing.assert_allclose(StreamingClassifier(bundle).run(x), expected, rtol=0, atol=1e-6)
    np.testing.assert_allclose(offline(bundle, x), expected, rtol=0, atol=1e-5)
    again = load_bundle(save_bundle(bundle, tmp_path / "again"))  # saved by today's code, read back
    assert again.family == name
    np.testing.assert_allclose(StreamingClassifier(again).run(x), expected, rtol=0, atol=1e-6)
    onnx = export_onnx(bundle, tmp_path / "step.onnx")
    assert check_onnx(onnx, bundle, x[:120]) < 1e-5


@pytest.mark.parametrize("name", FAMILIES)
def test_torch_export_writes_the_same_numbers_as_the_torchscript_exporter(name: str, tmp_path: Path) -> None:
    """The exporter a torch without the TorchScript one falls back to (``export_onnx(dynamo=None)``)."""
    x = np.load(GOLDEN / "log.npy")
    bundle = load_bundle(GOLDEN / name)
    script = export_onnx(bundle, tmp_path / "script.onnx", dynamo=False)
    dynamo = export_onnx(bundle, tmp_path / "dynamo.onnx", dynamo=True)
    assert check_onnx(dynamo, bundle, x[:120]) < 1e-5
    np.testing.assert_allclose(run_onnx(dynamo, bundle, x[:120]), run_onnx(script, bundle, x[:120]), atol=1e-6)
