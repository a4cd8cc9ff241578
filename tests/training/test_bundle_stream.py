"""Bundles round-trip without pickle; streaming, ONNX and the offline pass give the same numbers."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from training import (
    Classifier,
    ClassifierConfig,
    Normalizer,
    Predictor,
    PredictorConfig,
    run_classifiers,
    run_predictor,
)
from training.runtime.bundle import BundleError, ModelBundle, load_bundle, save_bundle
from training.runtime.stream import StreamingClassifier


def tiny_bundle(mode: str = "hidden", seed: int = 0) -> tuple[ModelBundle, list[np.ndarray]]:
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    logs = [rng.normal(5.0, 2.0, size=(n, 3)).astype(np.float32) for n in (120, 77)]
    pred = Predictor(PredictorConfig(3, 8)).eval()
    n_feat = {"hidden": 8, "estimate": 3, "error": 3, "hidden+error": 11, "surprise": 3, "hidden+surprise": 11}[mode]
    clfs = [Classifier(ClassifierConfig(n_feat, 4, 6, 0.2)).eval() for _ in range(3)]
    for c in clfs:  # a standardisation that is not the identity, so every path must apply it
        c.set_standardisation(rng.normal(0.0, 0.5, n_feat), rng.uniform(0.2, 3.0, n_feat))
    bundle = ModelBundle(
        pred,
        Normalizer.fit(logs),
        ("a", "b", "c"),
        100.0,
        clfs,
        ("w", "x", "y", "z"),
        mode,
        {"accuracy": 0.5},
        {"note": "tiny"},
    )
    return bundle, logs


def offline(bundle: ModelBundle, logs: list[np.ndarray]) -> list[np.ndarray]:
    outs = run_predictor(bundle.predictor, bundle.normalizer, logs, chunk=50)
    feats = [o.features(bundle.feature_mode) for o in outs]
    return [p.mean(0) for p in run_classifiers(bundle.classifiers, feats, chunk=33)]


def test_bundle_round_trip_is_exact_and_pickle_free(tmp_path: Path) -> None:
    bundle, logs = tiny_bundle()
    path = save_bundle(bundle, tmp_path / "v1")
    assert sorted(p.name for p in path.iterdir()) == ["classifier.safetensors", "model.json", "predictor.safetensors"]
    cfg = json.loads((path / "model.json").read_text())
    assert cfg["predictor"] == {"n_channels": 3, "hidden": 8} and cfg["n_folds"] == 3 and cfg["schema"] == 1
    again = load_bundle(path)
    assert again.classes == bundle.classes and again.channels == bundle.channels and again.info == {"note": "tiny"}
    for a, b in zip(offline(bundle, logs), offline(again, logs), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(FileExistsError):
        save_bundle(bundle, path)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp")]


def test_bundles_from_before_the_input_standardisation_load_as_identity(tmp_path: Path) -> None:
    from safetensors.torch import load_file, save_file

    bundle, logs = tiny_bundle()
    for c in bundle.classifiers:
        c.set_standardisation(np.zeros(8), np.ones(8))
    path = save_bundle(bundle, tmp_path / "old")
    weights = load_file(path / "classifier.safetensors")
    save_file({k: v for k, v in weights.items() if ".in_" not in k}, path / "classifier.safetensors")
    again = load_bundle(path)
    for a, b in zip(offline(bundle, logs), offline(again, logs), strict=True):
        np.testing.assert_array_equal(a, b)


def test_damaged_or_newer_bundles_are_refused(tmp_path: Path) -> None:
    bundle, _ = tiny_bundle()
    path = save_bundle(bundle, tmp_path / "v1")
    (path / "predictor.safetensors").write_bytes(b"garbage")
    with pytest.raises(BundleError, match="damaged model bundle"):
        load_bundle(path)
    path = save_bundle(bundle, tmp_path / "v2")
    cfg = json.loads((path / "model.json").read_text())
    cfg["schema"] = 99
    (path / "model.json").write_text(json.dumps(cfg))
    with pytest.raises(BundleError, match="newer"):
        load_bundle(path)
    with pytest.raises(BundleError, match="not a model bundle"):
        load_bundle(tmp_path)


@pytest.mark.parametrize("mode", ["hidden", "estimate", "error", "hidden+error", "surprise", "hidden+surprise"])
def test_streaming_equals_the_offline_pass(mode: str) -> None:
    bundle, logs = tiny_bundle(mode)
    expected = offline(bundle, logs)
    for log, exp in zip(logs, expected, strict=True):
        got = StreamingClassifier(bundle).run(log)
        np.testing.assert_allclose(got, exp, atol=1e-5)
    # several robots at once, each with its own state
    multi = StreamingClassifier(bundle, streams=2)
    n = min(len(x) for x in logs)
    out = np.stack([multi.step(np.stack([logs[0][t], logs[1][t]])) for t in range(n)])  # (T, 2, K)
    np.testing.assert_allclose(out[:, 0], expected[0][:n], atol=1e-5)
    np.testing.assert_allclose(out[:, 1], expected[1][:n], atol=1e-5)


@pytest.mark.parametrize("mode", ["hidden", "estimate", "hidden+error", "hidden+surprise"])
def test_one_member_streams_the_first_fold_models_offline_pass(mode: str) -> None:
    bundle, logs = tiny_bundle(mode)
    first = replace(bundle, classifiers=bundle.classifiers[:1])
    expected = offline(first, logs)
    assert not np.allclose(expected[0], offline(bundle, logs)[0], atol=1e-3)  # the ensemble's mean differs
    for log, exp in zip(logs, expected, strict=True):
        np.testing.assert_allclose(StreamingClassifier(bundle, members=1).run(log), exp, atol=1e-5)
    multi = StreamingClassifier(bundle, streams=2, members=1)
    n = min(len(x) for x in logs)
    out = np.stack([multi.step(np.stack([logs[0][t], logs[1][t]])) for t in range(n)])  # (T, 2, K)
    np.testing.assert_allclose(out[:, 1], expected[1][:n], atol=1e-5)
    multi.reset()  # a restarted robot: the same numbers again from its first sample
    np.testing.assert_allclose(multi.step(np.stack([logs[0][0], logs[1][0]]))[0], expected[0][0], atol=1e-5)
    two = StreamingClassifier(bundle, members=2).run(logs[0])
    np.testing.assert_allclose(two, offline(replace(bundle, classifiers=bundle.classifiers[:2]), logs)[0], atol=1e-5)
    for bad in (0, 4):
        with pytest.raises(ValueError, match="members must be 1 to 3"):
            StreamingClassifier(bundle, members=bad)


@pytest.mark.parametrize("mode", ["hidden", "hidden+error", "surprise", "hidden+surprise"])
def test_bfloat16_streaming_stays_close_to_the_offline_pass(mode: str) -> None:
    bundle, logs = tiny_bundle(mode)
    expected = offline(bundle, logs)[0]
    got = StreamingClassifier(bundle, precision="bfloat16").run(logs[0])
    assert got.shape == expected.shape
    assert np.abs(got - expected).max() < 2e-3  # bfloat16 keeps 8 bits of mantissa; measured ~1e-4
    assert (got.argmax(1) == expected.argmax(1)).mean() > 0.95
    with pytest.raises(ValueError, match="precision"):
        StreamingClassifier(bundle, precision="int4")


def test_onnx_matches_pytorch(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    from training.runtime.onnx_export import check_onnx, export_onnx, run_onnx

    bundle, logs = tiny_bundle("surprise")
    path = export_onnx(bundle, tmp_path / "classifier.onnx")
    assert check_onnx(path, bundle, logs[0]) < 1e-4
    np.testing.assert_allclose(run_onnx(path, bundle, logs[1]), offline(bundle, [logs[1]])[0], atol=1e-4)


@pytest.mark.parametrize("where", ["classifier.safetensors", "predictor.safetensors"])
def test_a_bundle_holding_nan_weights_is_refused_at_load(tmp_path: Path, where: str) -> None:
    """Issue 64, item 2: NaN weights gave NaN probabilities, read as the first terrain, with exit 0. The streaming
    runtime takes a loaded bundle, so it refuses the same; and its filter refuses a time on a terrain past a day."""
    from safetensors.torch import load_file, save_file

    bundle, _ = tiny_bundle()
    path = save_bundle(bundle, tmp_path / "b")
    weights = load_file(path / where)
    key = sorted(weights)[-1]
    weights[key] = weights[key].clone().fill_(float("nan"))
    save_file(weights, path / where)
    with pytest.raises(BundleError, match=f"{where}: .*holds \\d+ NaN or infinite value"):
        load_bundle(path)
    for bad in (float("inf"), 1e308, float("nan"), 0.0):
        with pytest.raises(ValueError, match="at most 86400"):
            StreamingClassifier(bundle, smooth_s=bad)
    assert StreamingClassifier(bundle, smooth_s=86_400.0).filter is not None
