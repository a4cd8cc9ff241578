"""A fit keeps the networks it trained on the labels alone, and a later fit that would train the same network reads
it: the export's taught fit is the session's fit again with other pseudo-labels, and must come out as it would
have from scratch, in the time of its refits."""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.torch import load_file, save_file

from training import Normalizer, SpectralConfig, SpectralSteps, WindowFitConfig, fit_window_classifier, log_frames

RATE = 100.0
SETTINGS = WindowFitConfig(k_folds=2, epochs=8, refit_epochs=4, calibrate=False)


def _walk(n: int, terrain: int, rng: np.random.Generator) -> np.ndarray:
    t = np.arange(n) / RATE
    fast = np.sin(2 * np.pi * (8.0, 22.0, 37.0)[terrain] * t + rng.uniform(0, 6)) + 0.5 * rng.normal(size=n)
    return np.column_stack([fast, rng.normal(size=n)]).astype(np.float32)


@pytest.fixture(scope="module")
def inputs():
    rng = np.random.default_rng(0)
    terrains = [0, 1, 2] * 2
    arrays = [_walk(2000, k, rng) for k in terrains]
    normalizer, config = Normalizer.fit(arrays), SpectralConfig.for_log(arrays[0], RATE)
    feats = [SpectralSteps(log_frames(a, config, transform=normalizer), len(a), config) for a in arrays]
    segments = [(i, 200, 800, k) for i, k in enumerate(terrains)]
    stretches = [(i, 1000, 1800) for i in range(len(arrays))]
    fit = partial(fit_window_classifier, feats, segments, ("a", "b", "c"), config=SETTINGS, stretches=stretches)
    other = [(i, 300, 900, k) for i, k in enumerate(terrains)]  # the same logs labelled elsewhere
    refit = partial(fit_window_classifier, feats, other, ("a", "b", "c"), config=SETTINGS, stretches=stretches)
    return fit, [(k + 1) % 3 for k in terrains], refit  # a teacher wrong everywhere: the refits must show it


def _weights(fit) -> list[dict[str, torch.Tensor]]:
    return [m.state_dict() for m in fit.models]


def _same(a, b) -> bool:
    return all(x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x) for x, y in zip(a, b, strict=True))


def test_a_taught_fit_reads_the_networks_the_sessions_fit_kept_and_ends_as_from_scratch(inputs, tmp_path) -> None:
    fit, teacher, _ = inputs
    session_fit = fit(starts=tmp_path)
    kept = sorted(tmp_path.glob("*.safetensors"))
    assert len(kept) == 2 + session_fit.metrics["held_out_logs"]["folds"]  # every member and every fold over runs
    from_scratch = fit(taught=teacher)
    started = fit(taught=teacher, starts=tmp_path)
    assert _same(_weights(started), _weights(from_scratch))
    assert started.metrics == from_scratch.metrics
    assert not _same(_weights(started), _weights(session_fit))  # the teacher changed the refits
    assert sorted(tmp_path.glob("*.safetensors")) == kept  # nothing new: every network was read


def test_a_kept_network_is_what_the_fit_starts_from(inputs, tmp_path: Path) -> None:
    """Replace the kept networks by others of the same shape: the fit that reads them ends elsewhere, so it read
    them (and a fit that trained them again could not)."""
    fit, teacher, _ = inputs
    fit(starts=tmp_path)
    from_scratch = fit(taught=teacher)
    for path in tmp_path.glob("*.safetensors"):
        w = load_file(path)
        save_file({k: v if "in_" in k else torch.zeros_like(v) for k, v in w.items()}, path)
    assert not _same(_weights(fit(taught=teacher, starts=tmp_path)), _weights(from_scratch))


def test_a_damaged_or_stale_start_is_trained_again(inputs, tmp_path: Path) -> None:
    fit, teacher, other_labels = inputs
    fit(starts=tmp_path)
    assert _same(_weights(other_labels(starts=tmp_path)), _weights(other_labels()))  # other rows: none read
    for path in tmp_path.glob("*.safetensors"):
        path.write_bytes(b"not a safetensors file")
    assert _same(_weights(fit(taught=teacher, starts=tmp_path)), _weights(fit(taught=teacher)))
    # other settings are other networks: a key of their own, nothing of the first fit's read
    before = set(tmp_path.glob("*.safetensors"))
    fit(config=WindowFitConfig(k_folds=2, epochs=9, refit_epochs=4, calibrate=False, held_out=False), starts=tmp_path)
    assert len(set(tmp_path.glob("*.safetensors")) - before) == 2


def test_the_folder_keeps_the_newest_networks_only(inputs, tmp_path: Path, monkeypatch) -> None:
    import training.spectral_cnn.fit_starts as fit_starts

    monkeypatch.setattr(fit_starts, "KEPT", 3)
    fit, _, _ = inputs
    fit(config=WindowFitConfig(k_folds=2, epochs=8, refit_epochs=4, calibrate=False, held_out=False), starts=tmp_path)
    fit(config=WindowFitConfig(k_folds=2, epochs=9, refit_epochs=4, calibrate=False, held_out=False), starts=tmp_path)
    assert len(list(tmp_path.glob("*.safetensors"))) == 3 and not list(tmp_path.glob(".*"))
