"""A default-family bundle scored in NumPy alone: the same numbers as the PyTorch pass, the same refusals as
``load_bundle``, and PyTorch never loaded."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.numpy import load_file, save_file

from training import (
    BundleError,
    ModelBundle,
    Normalizer,
    Predictor,
    PredictorConfig,
    SpectralConfig,
    SpectralSteps,
    WindowClassifier,
    WindowClassifierConfig,
    blank_probs,
    fit_drift,
    frame_chunks,
    load_bundle,
    load_scoring_bundle,
    log_frames,
    save_bundle,
)

RATE = 50.0


def _log(n: int, seed: int) -> np.ndarray:
    """Three channels: two vibrating at a seed's frequencies, one held in steps."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / RATE
    fast = np.sin(2 * np.pi * (5.0 + 3.0 * seed) * t) + 0.4 * rng.normal(size=n)
    held = np.repeat(rng.normal(size=n // 10 + 1), 10)[:n]
    return np.column_stack([fast, rng.normal(size=n), held]).astype(np.float32)


@pytest.fixture(scope="module")
def bundle_dir(tmp_path_factory) -> Path:
    """A saved bundle of three untrained members (seeded weights, a non-trivial standardisation) with a drift
    reference: the numbers, not the accuracy, are under test."""
    logs = [_log(1500, s) for s in range(3)]
    normalizer = Normalizer.fit(logs)
    config = SpectralConfig.for_log(logs[0], RATE)
    torch.manual_seed(0)
    models = []
    for _ in range(3):
        model = WindowClassifier(WindowClassifierConfig(config.step_width, 4, window=config.window, hidden=16))
        f = config.step_width // config.window
        model.set_standardisation(np.random.default_rng(1).normal(size=f), np.random.default_rng(2).uniform(0.5, 2, f))
        models.append(model.eval())
    steps = [SpectralSteps(log_frames(x, config, transform=normalizer), len(x), config) for x in logs]
    rows = [s[300:1500][::5] for s in steps]  # (N, W·F) stacked-frame rows
    drift = fit_drift(models, rows, rows[1:] + rows[:1])
    bundle = ModelBundle(
        Predictor(PredictorConfig(3, 8)),
        normalizer,
        ("fast", "noise", "held"),
        RATE,
        classifiers=models,
        classes=("a", "b", "c", "d"),
        feature_mode="spectral",
        spectral=config,
        drift=drift,
    )
    return save_bundle(bundle, tmp_path_factory.mktemp("scoring") / "bundle")


def test_the_numpy_members_give_the_pytorch_pass_numbers(bundle_dir: Path) -> None:
    """Probabilities and drift within 1e-5 of the PyTorch pass on every frame, the same most probable class; the
    blank input's answer too."""
    arrays, torch_bundle = load_scoring_bundle(bundle_dir), load_bundle(bundle_dir)
    assert arrays is not None and len(arrays.members) == 3 and arrays.classes == ("a", "b", "c", "d")
    x = _log(4000, 7)
    steps = SpectralSteps(log_frames(x, arrays.spectral, transform=arrays.normalizer), len(x), arrays.spectral)
    ours = list(arrays.members.chunks(steps, drift=arrays.drift, chunk=100))  # several chunks, a window across each
    theirs = list(frame_chunks(torch_bundle.classifiers, steps, drift=torch_bundle.drift, chunk=100))
    assert [c.start for c in ours] == [c.start for c in theirs] and len(ours) > 3
    probs, expected = (np.concatenate([c.probs for c in chunks], axis=1) for chunks in (ours, theirs))  # (M, N, K)
    np.testing.assert_allclose(probs, expected, atol=1e-5)
    np.testing.assert_array_equal(probs.mean(axis=0).argmax(axis=1), expected.mean(axis=0).argmax(axis=1))
    drift = np.concatenate([c.drift for c in ours])
    np.testing.assert_allclose(drift, np.concatenate([c.drift for c in theirs]), rtol=1e-5, atol=1e-5)
    assert drift.std() > 0.01  # the drift varies: a constant would pass the comparison too
    np.testing.assert_allclose(arrays.members.blank(), blank_probs(torch_bundle.classifiers), atol=1e-5)
    # on frames the reference holds (a log it was drawn from) a distance is near 0, and its float32 form (squared
    # norms less twice the products) turns the two passes' last-bit differences into up to 3e-4 of the drift (measured)
    own = SpectralSteps(log_frames(_log(1500, 0), arrays.spectral, transform=arrays.normalizer), 1500, arrays.spectral)
    ours, theirs = (
        np.concatenate([c.drift for c in chunks])
        for chunks in (
            arrays.members.chunks(own, drift=arrays.drift),
            frame_chunks(torch_bundle.classifiers, own, drift=torch_bundle.drift),
        )
    )
    np.testing.assert_allclose(ours, theirs, rtol=1e-3)


def test_a_bundle_of_another_family_or_without_a_classifier_is_left_to_load_bundle(tmp_path: Path) -> None:
    config = json.loads((Path(__file__).parent / "golden" / "paper" / "model.json").read_text())
    folder = tmp_path / "paper"
    folder.mkdir()
    (folder / "model.json").write_text(json.dumps(config))
    assert load_scoring_bundle(folder) is None
    (folder / "model.json").write_text(json.dumps({**config, "classifier": None}))
    assert load_scoring_bundle(folder) is None


def test_damaged_or_tampered_files_are_refused_as_load_bundle_refuses_them(bundle_dir: Path, tmp_path: Path) -> None:
    def copy(name: str) -> Path:
        folder = tmp_path / name
        folder.mkdir()
        for f in bundle_dir.iterdir():
            (folder / f.name).write_bytes(f.read_bytes())
        return folder

    grown = copy("grown")  # sizes past what the weights hold: refused from the header, nothing allocated
    cfg = json.loads((grown / "model.json").read_text())
    cfg["classifier"]["hidden"] = 10**9
    (grown / "model.json").write_text(json.dumps(cfg))
    with pytest.raises(BundleError, match="does not match the weights"):
        load_scoring_bundle(grown)
    nan = copy("nan")
    weights = load_file(nan / "classifier.safetensors")
    weights["fold1.head.bias"][2] = np.nan
    save_file(weights, nan / "classifier.safetensors")
    with pytest.raises(BundleError, match=r"classifier.safetensors: fold1.head.bias holds 1 NaN"):
        load_scoring_bundle(nan)
    with pytest.raises(BundleError, match=r"classifier.safetensors: fold1.head.bias holds 1 NaN"):
        load_bundle(nan)
    fewer = copy("fewer")
    cfg = json.loads((fewer / "model.json").read_text())
    cfg["n_folds"] = 2
    (fewer / "model.json").write_text(json.dumps(cfg))
    with pytest.raises(BundleError, match="names 2 ensemble members, the weights hold 3"):
        load_scoring_bundle(fewer)
    gone = copy("gone")
    (gone / "drift.safetensors").unlink()
    with pytest.raises(BundleError, match="damaged model bundle"):
        load_scoring_bundle(gone)
    newer = copy("newer")
    cfg = json.loads((newer / "model.json").read_text())
    (newer / "model.json").write_text(json.dumps({**cfg, "schema": 99}))
    with pytest.raises(BundleError, match="newer than this workbench"):
        load_scoring_bundle(newer)


def test_reading_and_scoring_a_bundle_never_loads_pytorch(bundle_dir: Path) -> None:
    code = (
        "import sys, numpy as np\n"
        "from training import SpectralSteps, load_scoring_bundle, log_frames\n"
        f"b = load_scoring_bundle({str(bundle_dir)!r})\n"
        "x = np.random.default_rng(0).normal(size=(2000, 3)).astype(np.float32)\n"
        "steps = SpectralSteps(log_frames(x, b.spectral, transform=b.normalizer), len(x), b.spectral)\n"
        "n = sum(c.probs.shape[1] for c in b.members.chunks(steps, drift=b.drift))\n"
        "print(n, 'torch' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    frames, torch_loaded = done.stdout.split()
    assert int(frames) > 0 and torch_loaded == "False"
