"""Temperature scaling of the default family's ensemble (Guo et al., 2017): one number divides every member's
logits, fitted on predictions of labelled time the member never trained on, and folded into the members' heads, so
the streaming step, ONNX and the offline passes need no change.

Fitted on held-out logs where the session has them: on new runs the network is overconfident (BorealTC's folds by
run: calibration error up to 0.21 at 10 % of labels), and same-run folds, whose predictions are nearly always right,
would not see it. The temperature minimises the Brier score, not the negative log-likelihood: on BorealTC's inner
folds by run (a temperature fitted on four held-out-run folds, scored on the fifth) the Brier rule left a calibration
error of 0.139, the likelihood 0.150 (a few confidently wrong steps of a new run pull its temperature up).
"""

from __future__ import annotations

import numpy as np
import torch

from .window_classifier import WindowClassifier

TEMPERATURES = np.exp(np.linspace(np.log(0.25), np.log(16.0), 121))  # a 3.5 % step: finer than any NLL minimum


def brier(logits: np.ndarray, truth: np.ndarray, temperature: float) -> float:
    """Mean Brier score of ``softmax(logits / temperature)`` ``(N, K)`` against classes ``truth (N,)``."""
    z = logits / temperature  # (N, K)
    z = z - z.max(axis=1, keepdims=True)
    p = np.exp(z)
    p /= p.sum(axis=1, keepdims=True)
    p[np.arange(len(truth)), truth] -= 1.0
    return float(np.square(p).sum(axis=1).mean())


def fit_temperature(logits: np.ndarray, truth: np.ndarray) -> float:
    """The temperature of least Brier score on ``logits (N, K)`` with classes ``truth (N,)``, searched on a log grid
    from 0.25 to 16 (a grid: the score is one-dimensional and smooth, and a grid cannot diverge).

    Returns 1.0 when there is nothing to fit.
    """
    logits = np.asarray(logits, np.float64)
    truth = np.asarray(truth, np.int64)
    if len(truth) == 0:
        return 1.0
    losses = [brier(logits, truth, t) for t in TEMPERATURES]
    return float(TEMPERATURES[int(np.argmin(losses))])


@torch.no_grad()
def scale_head(model: WindowClassifier, temperature: float) -> None:
    """Divide the model's logits by ``temperature`` by scaling its head (its argmax is unchanged)."""
    if temperature != 1.0:
        model.head.weight.div_(temperature)
        model.head.bias.div_(temperature)
