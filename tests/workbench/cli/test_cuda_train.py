"""``workbench train --device cuda`` with the default family, end to end: both stages fit on the GPU, the versions
are saved and load on the CPU, and the classifier scores as one trained on the CPU would (same terrains, accuracy
within a few points). Skipped where no CUDA device is present (``make test`` never needs one)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import torch

from sessions import Session
from tests.conftest import new_session
from training import load_bundle
from workbench.cli import main
from workbench.demo import generate_demo_logs, seed_labels

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device on this machine")


def test_train_on_cuda_gives_a_default_family_model_like_the_cpus(tmp_path: Path) -> None:
    logs = generate_demo_logs(tmp_path / "logs", n_logs=3, minutes=1.5, seed=5)
    with new_session(tmp_path / "cpu") as s:
        s.ingest(logs)
        seed_labels(s, 0.2, seed=1)
    shutil.copytree(tmp_path / "cpu", tmp_path / "gpu")
    assert main(["train", str(tmp_path / "cpu")]) == 0
    assert main(["train", str(tmp_path / "gpu"), "--device", "cuda"]) == 0
    accuracy = {}
    for name in ("cpu", "gpu"):
        with Session.open(tmp_path / name) as s:
            p, c = s.active_model("predictor"), s.active_model("classifier")
            assert p is not None and c is not None and c.config["model"] == "default"
            bundle = load_bundle(s.path / c.path)
            assert all(next(m.parameters()).device.type == "cpu" for m in bundle.classifiers)
            accuracy[name] = c.metrics["accuracy"]
    assert accuracy["gpu"] == pytest.approx(accuracy["cpu"], abs=0.05)
    assert main(["export", str(tmp_path / "gpu"), "--out", str(tmp_path / "x"), "--predictions"]) == 0
