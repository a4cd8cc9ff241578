"""A terrain with little labelled time keeps its weight in the window network's loss: the three ways of
``WindowFitConfig.balance``, and a minority terrain of a generated session recalled above chance."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch.nn import functional as F

from training import Normalizer, SpectralConfig, WindowFitConfig, fit_window_classifier, run_classifiers
from training.spectral_cnn.class_balance import BalancedLoss, class_shares, epoch_order

from .test_window_family import RATE, _features, _walk


def test_logit_adjustment_adds_the_log_prior_and_leaves_an_absent_class_alone() -> None:
    prior = class_shares(np.array([0] * 90 + [1] * 10), 3)  # class 2 absent
    np.testing.assert_allclose(prior, [0.9, 0.1, 0.0])
    logits, y = torch.randn(8, 3), torch.tensor([0, 1, 0, 1, 0, 0, 1, 0])
    want = F.cross_entropy(logits + torch.tensor([np.log(0.9), np.log(0.1), 0.0], dtype=torch.float32), y)
    assert torch.isclose(BalancedLoss("logits", prior)(logits, y), want)
    assert torch.isclose(BalancedLoss("none", prior)(logits, y), F.cross_entropy(logits, y))


def test_weights_give_each_class_present_the_same_total_and_sampling_draws_them_evenly() -> None:
    y = np.array([0] * 900 + [1] * 100)
    loss = BalancedLoss("weights", class_shares(y, 3))
    assert loss.weight is not None
    np.testing.assert_allclose((loss.weight.numpy() * np.bincount(y, minlength=3)), [500.0, 500.0, 0.0], rtol=1e-6)
    drawn = y[epoch_order(torch.from_numpy(y), "sampling", torch.Generator().manual_seed(0)).numpy()]
    assert len(drawn) == len(y) and 0.45 < (drawn == 1).mean() < 0.55
    assert sorted(epoch_order(torch.from_numpy(y), "none", torch.Generator().manual_seed(0)).tolist()) == list(
        range(1000)
    )
    with pytest.raises(ValueError, match="unknown balance"):
        BalancedLoss("square", class_shares(y, 3))  # type: ignore[arg-type]


def test_a_minority_terrain_of_a_generated_session_is_recalled_above_chance() -> None:
    # three terrains, three logs each; terrain c labelled for a twentieth of the others' time, in one log; scored on
    # the last three logs, one per terrain, which nothing trained on
    rng = np.random.default_rng(3)
    terrains = [0, 1, 2] * 3
    arrays = [_walk(2400, k, rng) for k in terrains]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    feats, new = _features(arrays[:6], normalizer, config), _features(arrays[6:], normalizer, config)
    segments = [(i, 200, 2200, k) for i, k in enumerate(terrains[:6]) if k != 2] + [(2, 500, 600, 2)]

    def recall_of_c(balance: str) -> float:
        config = WindowFitConfig(k_folds=2, epochs=30, held_out=False, balance=balance)  # type: ignore[arg-type]
        fit = fit_window_classifier(feats, segments, ("a", "b", "c"), config=config)
        probs = run_classifiers(fit.models, new[2:])[0].mean(0)  # (T, K) the new log of terrain c
        return float((probs.argmax(1)[300:] == 2).mean())

    balanced = recall_of_c(WindowFitConfig().balance)  # the default
    assert balanced > 1 / 3
    assert recall_of_c("none") < balanced - 0.2  # 0.20 against 0.80 when written
