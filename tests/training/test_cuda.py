"""Stage 1 on a GPU gives the CPU's result on a small fixed case: float32 within float tolerance, bf16 autocast
within the precision bfloat16 keeps. Skipped where no CUDA device is present (``make test`` never needs one)."""

from __future__ import annotations

import pytest
import torch

from training import TrainConfig, fit_predictor

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
