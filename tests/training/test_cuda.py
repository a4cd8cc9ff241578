"""A fit on a GPU gives the CPU's result on a small fixed case: the paper family's stage 1 (float32 within float
tolerance, bf16 autocast within the precision bfloat16 keeps), the default family's frame predictor and window
classifier. Skipped where no CUDA device is present (``make test`` never needs one)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from training import (
    FramePredictorFit,
    Normalizer,
    SpectralConfig,
    TrainConfig,
    WindowFitConfig,
    fit_frame_predictor,
    fit_predictor,
    fit_window_classifier,
    run_classifiers,
)

from .test_checkpoint import SMALL
from .test_models import sine_logs

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device on this machine")


@pytest.mark.parametrize(("bf16", "rel"), [(False, 1e-3), (True, 5e-2)], ids=["float32", "bf16-autocast"])
def test_a_gpu_fit_matches_the_cpu_fit(bf16: bool, rel: float) -> None:
    logs = sine_logs(8, 256)
    cpu = fit_predictor(logs, config=SMALL, hidden=8)
    gpu = fit_predictor(logs, config=TrainConfig(**{**SMALL.__dict__, "device": "cuda", "bf16": bf16}), hidden=8)
    for a, b in zip(cpu.history, gpu.history, strict=True):
        assert b["train_loss"] == pytest.approx(a["train_loss"], rel=rel)
        assert b["val_loss"] == pytest.approx(a["val_loss"], rel=rel)
    assert next(gpu.model.parameters()).device.type == "cpu"  # handed back on the CPU, as every fit is


def _window_data():
    from .test_window_family import RATE, _features, _walk

    rng = np.random.default_rng(0)
    terrains = [0, 1, 2] * 3
    arrays = [_walk(2400, k, rng) for k in terrains]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    feats = _features(arrays, normalizer, config)
    segments = [(i, 300, 900, k) for i, k in enumerate(terrains)]
    stretches = [(i, 1000, 1500) for i in range(len(arrays))] + [(i, 1500, 2000) for i in range(len(arrays))]
    return feats, segments, stretches


def test_the_default_familys_gpu_fit_matches_its_cpu_fit() -> None:
    """The same fit (same seeds, the same batches and noise drawn on the CPU) on either device: float rounding
    apart, the same models. Short (a few hundred steps) so that rounding cannot grow into another model."""
    feats, segments, stretches = _window_data()
    settings = WindowFitConfig(k_folds=3, epochs=4, refit_epochs=2)
    cpu = fit_window_classifier(feats, segments, ("a", "b", "c"), config=settings, stretches=stretches)
    gpu = fit_window_classifier(feats, segments, ("a", "b", "c"), config=settings, stretches=stretches, device="cuda")
    assert all(next(m.parameters()).device.type == "cpu" for m in gpu.models)  # handed back on the CPU
    for a, b in zip(cpu.models, gpu.models, strict=True):
        for (name, p), q in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
            assert torch.allclose(p, q, rtol=1e-3, atol=1e-3), name
    assert gpu.metrics["accuracy"] == pytest.approx(cpu.metrics["accuracy"], abs=0.02)
    assert gpu.metrics["pseudo_stretches"] == cpu.metrics["pseudo_stretches"]
    # the same weights score the same on either device (the offline pass the UI and export run)
    on_cpu = run_classifiers(cpu.models, feats[:2])
    on_gpu = run_classifiers(cpu.models, feats[:2], device="cuda")
    for a, b in zip(on_cpu, on_gpu, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-4)


def test_the_frame_predictors_gpu_fit_matches_its_cpu_fit() -> None:
    feats, _, _ = _window_data()
    frames = [f.frames for f in feats]
    fit = FramePredictorFit(steps=100, batch=16, crop=48)
    cpu, cpu_history = fit_frame_predictor(frames, fit=fit)
    gpu, gpu_history = fit_frame_predictor(frames, fit=fit, device="cuda")
    assert next(gpu.parameters()).device.type == "cpu"
    np.testing.assert_allclose(gpu_history, cpu_history, rtol=1e-3)
    np.testing.assert_allclose(gpu.residual_inv.numpy(), cpu.residual_inv.numpy(), rtol=1e-2)
