"""The paper's losses against values computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from torch import nn

from training import ElasticNet, classifier_loss, elastic_net, predictor_loss
from training.paper_lstm import consistency_loss, masked_mse
from training.paper_lstm.lstm_losses import lstm_parameters, masked_cross_entropy


def test_elastic_net_by_hand() -> None:
    params = [torch.tensor([1.0, -2.0]), torch.tensor([[0.5], [-0.5]])]
    # L1 = 1 + 2 + 0.5 + 0.5 = 4 ; L2² = 1 + 4 + 0.25 + 0.25 = 5.5
    assert float(elastic_net(params, ElasticNet(lam=0.1, gamma=0.25))) == pytest.approx(0.1 * (0.25 * 4 + 0.75 * 5.5))
    assert float(elastic_net(params, ElasticNet(lam=2.0, gamma=1.0))) == pytest.approx(8.0)  # pure lasso
    assert float(elastic_net(params, ElasticNet(lam=2.0, gamma=0.0))) == pytest.approx(11.0)  # pure ridge


def test_penalty_covers_the_lstm_w_u_b_only() -> None:
    lstm = nn.LSTM(3, 4, batch_first=True)
    names = sorted(n for n, _ in lstm.named_parameters())
    assert names == ["bias_hh_l0", "bias_ih_l0", "weight_hh_l0", "weight_ih_l0"]
    assert len(lstm_parameters(lstm)) == 4


def test_masked_mse_by_hand() -> None:
    est = torch.tensor([[[1.0, 1.0], [2.0, 0.0], [9.0, 9.0]]])  # (1, 3, 2)
    tgt = torch.tensor([[[0.0, 1.0], [0.0, 0.0], [0.0, 0.0]]])
    mask = torch.tensor([[True, True, False]])
    # step 0: ((1)^2 + 0)/2 = 0.5 ; step 1: (4 + 0)/2 = 2 ; step 2 masked -> mean 1.25
    assert float(masked_mse(est, tgt, mask)) == pytest.approx(1.25)


def test_cross_entropy_is_minus_sum_y_log_yhat() -> None:
    logits = torch.tensor([[[math.log(0.7), math.log(0.2), math.log(0.1)], [0.0, 0.0, 0.0]]])  # (1, 2, 3)
    labels = torch.tensor([[0, 2]])
    mask = torch.tensor([[True, False]])
    assert float(masked_cross_entropy(logits, labels, mask)) == pytest.approx(-math.log(0.7))
    mask = torch.tensor([[True, True]])
    assert float(masked_cross_entropy(logits, labels, mask)) == pytest.approx((-math.log(0.7) + math.log(3)) / 2)


def test_full_losses_add_the_penalty() -> None:
    torch.manual_seed(0)
    lstm = nn.LSTM(2, 3)
    pen = ElasticNet(lam=0.01, gamma=0.5)
    est, tgt, mask = torch.ones(1, 2, 2), torch.zeros(1, 2, 2), torch.ones(1, 2, dtype=torch.bool)
    expected = 1.0 + elastic_net(lstm_parameters(lstm), pen).item()
    assert predictor_loss(est, tgt, mask, lstm, pen).item() == pytest.approx(expected)
    logits, labels = torch.zeros(1, 2, 4), torch.zeros(1, 2, dtype=torch.long)
    expected = math.log(4) + elastic_net(lstm_parameters(lstm), pen).item()
    assert classifier_loss(logits, labels, mask, lstm, pen).item() == pytest.approx(expected)


def test_class_weights_make_each_class_count_by_its_weight() -> None:
    from training.paper_lstm import balanced_weights

    # 3 steps of class 0 (p = 0.7 each), 1 step of class 2 (p = 0.1)
    logits = torch.log(torch.tensor([[[0.7, 0.2, 0.1]] * 3 + [[0.2, 0.7, 0.1]]]))  # (1, 4, 3)
    labels, mask = torch.tensor([[0, 0, 0, 2]]), torch.ones(1, 4, dtype=torch.bool)
    w = balanced_weights([(0, 0, 3, 0), (0, 3, 4, 2)], 3)
    np.testing.assert_allclose(w, [4 / 6, 0.0, 2.0])  # inverse to steps, mean 1 over labelled steps; absent: 0
    got = float(masked_cross_entropy(logits, labels, mask, torch.as_tensor(w, dtype=torch.float32)))
    assert got == pytest.approx((-math.log(0.7) - math.log(0.1)) / 2)  # both classes count the same
    assert float(masked_cross_entropy(logits, labels, mask)) == pytest.approx((-3 * math.log(0.7) - math.log(0.1)) / 4)


def test_consistency_loss_by_hand_reads_each_sequences_last_step() -> None:
    k = 2
    logits = torch.zeros(4, 3, k)  # (2P, T, K): pairs (0, 2) and (1, 3)
    logits[0, 1] = torch.tensor([math.log(3.0), 0.0])  # softmax (0.75, 0.25) at step 1, the last of a padded one
    logits[0, 2] = torch.tensor([50.0, 0.0])  # padding: must not be read
    last = torch.tensor([1, 2, 2, 2])
    # pair 0: (0.75, 0.25) against (0.5, 0.5) -> 0.125; pair 1: equal -> 0
    assert float(consistency_loss(logits, last)) == pytest.approx(0.0625)
    same = torch.randn(2, 5, 3).repeat(2, 1, 1)
    assert float(consistency_loss(same, torch.full((4,), 4))) == pytest.approx(0.0, abs=1e-7)
