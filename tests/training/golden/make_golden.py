"""Writes the golden bundles of ``tests/training/test_golden_bundles.py``: one tiny bundle per model family, a log to
score and the probabilities the code of the day gave for it. Run once, before a change to how bundles are saved,
loaded or scored; the test then holds every later version of the code to those numbers.

    python -m tests.training.golden.make_golden
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import torch

from training import (
    Classifier,
    ClassifierConfig,
    ModelBundle,
    Normalizer,
    Predictor,
    PredictorConfig,
    SpectralConfig,
    StreamingClassifier,
    WindowClassifier,
    WindowClassifierConfig,
    save_bundle,
)

HERE = Path(__file__).parent
RATE = 50.0


def golden_log(seed: int = 7) -> np.ndarray:
    """``(400, 3)``: a vibrating channel, a noise channel and a slowly held one."""
    rng = np.random.default_rng(seed)
    t = np.arange(400) / RATE
    fast = np.sin(2 * np.pi * 9.0 * t) + 0.3 * rng.normal(size=400)
    held = np.repeat(rng.normal(size=400 // 10), 10)
    return np.column_stack([fast, rng.normal(2.0, 1.5, 400), held]).astype(np.float32)


def paper_bundle(x: np.ndarray) -> ModelBundle:
    torch.manual_seed(1)
    rng = np.random.default_rng(1)
    members = [Classifier(ClassifierConfig(11, 3, 6, 0.2)).eval() for _ in range(2)]
    for m in members:
        m.set_standardisation(rng.normal(0.0, 0.5, 11), rng.uniform(0.5, 2.0, 11))
    return ModelBundle(
        Predictor(PredictorConfig(3, 8)).eval(),
        Normalizer.fit([x]),
        ("fast", "noise", "held"),
        RATE,
        members,
        ("grass", "gravel", "sand"),
        "hidden+surprise",
        {"accuracy": 0.5},
        {"golden": "paper"},
    )


def default_bundle(x: np.ndarray) -> ModelBundle:
    torch.manual_seed(2)
    rng = np.random.default_rng(2)
    front = SpectralConfig.for_log(x, RATE)
    members = [
        WindowClassifier(WindowClassifierConfig(front.step_width, 3, window=front.window, hidden=8)).eval()
        for _ in range(2)
    ]
    for m in members:
        m.set_standardisation(rng.normal(0.0, 0.5, front.width), rng.uniform(0.5, 2.0, front.width))
    return ModelBundle(
        Predictor(PredictorConfig(3, 8)).eval(),
        Normalizer.fit([x]),
        ("fast", "noise", "held"),
        RATE,
        members,
        ("grass", "gravel", "sand"),
        "spectral",
        {"accuracy": 0.5},
        {"golden": "default"},
        front,
    )


def main() -> None:
    x = golden_log()
    np.save(HERE / "log.npy", x)
    for name, bundle in (("paper", paper_bundle(x)), ("default", default_bundle(x))):
        shutil.rmtree(HERE / name, ignore_errors=True)
        save_bundle(bundle, HERE / name)
        np.save(HERE / f"{name}.stream.npy", StreamingClassifier(bundle).run(x))


if __name__ == "__main__":
    main()
