"""Fit a MiniRocket classifier on windows: the transform's biases from unlabelled windows, a ridge head on the
labelled ones (scikit-learn's ``RidgeClassifierCV``, as aeon's ``MiniRocketClassifier``), and a temperature that
turns its scores into probabilities, fitted on windows of groups the head did not see."""

from __future__ import annotations

import warnings

import numpy as np
import torch
from scipy.linalg import LinAlgWarning
from sklearn.linear_model import Ridge, RidgeClassifierCV
from sklearn.model_selection import GroupKFold

from .rocket_classifier import RocketClassifier, RocketClassifierConfig
from .rocket_kernels import RocketParameters, fit_rocket, on_grid

ALPHAS = np.logspace(-3, 3, 10)  # aeon's MiniRocketClassifier's ridge penalties
ABSENT = -1e3  # the score of a terrain with no labelled window: never predicted
TEMPERATURES = np.logspace(-3, 1, 81)  # ridge scores are near ±1: probabilities need a temperature far below 1
BATCH = 256  # windows per transform call: (B, 84, L, nf) comparisons stay within ~100 MB


def rocket_features(model: RocketClassifier, windows: np.ndarray) -> np.ndarray:
    """The classifier's MiniRocket features (before its scale) of ``windows (N, L, C)``: ``(N, F)`` float32, a
    batch at a time, the windows put on the grid as the classifier does."""
    out = []
    with torch.no_grad():
        for i in range(0, len(windows), BATCH):
            x = torch.as_tensor(np.ascontiguousarray(windows[i : i + BATCH], np.float32))
            out.append(model.transformed(x.flatten(1)).numpy())  # (B, F)
    return np.concatenate(out) if out else np.zeros((0, model.transform.config.features), np.float32)


def feature_scale(x: np.ndarray) -> np.ndarray:
    """1 / each feature's spread over ``x (N, F)`` (1 where it has none): aeon's ``StandardScaler(with_mean=False)``."""
    spread = x.std(0)
    return np.where(spread > 1e-8, 1.0 / np.maximum(spread, 1e-8), 1.0).astype(np.float32)


def ridge_head(x: np.ndarray, y: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Ridge scores for ``k`` terrains from scaled features ``x (N, F)`` of terrains ``y``: weights ``(K, F)``,
    biases ``(K,)`` (a terrain with no window scores :data:`ABSENT`) and the penalty chosen by leave-one-out."""
    present = np.unique(y)
    ridge = RidgeClassifierCV(alphas=ALPHAS).fit(x, y)
    coef, intercept = ridge.coef_.reshape(-1, x.shape[1]), np.atleast_1d(ridge.intercept_)
    if len(present) == 2:  # one column: its negation scores the first terrain
        coef, intercept = np.concatenate([-coef, coef]), np.concatenate([-intercept, intercept])
    w = np.zeros((k, x.shape[1]), np.float32)
    b = np.full(k, ABSENT, np.float32)
    w[present], b[present] = coef, intercept
    return w, b, float(ridge.alpha_)


def held_out_scores(
    x: np.ndarray, y: np.ndarray, groups: np.ndarray, alpha: float, k: int, *, folds: int = 5
) -> np.ndarray:
    """Each window's ridge scores ``(N, K)`` from a head at ``alpha`` fitted without its group's windows (at most
    ``folds`` folds over the groups; all :data:`ABSENT` with fewer than two groups)."""
    scores = np.full((len(y), k), ABSENT, np.float32)
    n = min(folds, len(np.unique(groups)))
    if n < 2:
        return scores
    present = np.unique(y)
    targets = np.where(y[:, None] == present[None, :], 1.0, -1.0)  # (N, P): RidgeClassifier's ±1 coding
    with warnings.catch_warnings():
        # overlapping windows make the dual's Gram matrix near singular at small penalties; the least-squares
        # solution scikit-learn falls back to is the one wanted
        warnings.simplefilter("ignore", LinAlgWarning)
        warnings.simplefilter("ignore", UserWarning)
        for train, test in GroupKFold(n).split(x, y, groups):
            ridge = Ridge(alpha=alpha).fit(x[train], targets[train])
            scores[test[:, None], present[None, :]] = ridge.predict(x[test]).reshape(len(test), -1)
    return scores


def fit_temperature_nll(scores: np.ndarray, y: np.ndarray) -> float:
    """The temperature whose softmax of ``scores (N, K)`` gives the held-out labels ``y`` the highest likelihood
    (1.0 with nothing to fit)."""
    if len(y) == 0:
        return 1.0
    best, best_nll = 1.0, np.inf
    for t in TEMPERATURES:
        z = scores / t
        z = z - z.max(1, keepdims=True)
        nll = float(np.mean(np.log(np.exp(z).sum(1)) - z[np.arange(len(y)), y]))
        if nll < best_nll:
            best, best_nll = float(t), nll
    return best


def rocket_model(
    params: RocketParameters, n_classes: int, *, hop: int = 1, head: tuple[np.ndarray, ...] | None = None
) -> RocketClassifier:
    """A classifier of the transform ``params``; ``head``: its ``(scale, weights, biases, temperature)``."""
    cfg = params.config
    config = RocketClassifierConfig(cfg.length, cfg.channels, cfg.dilations, cfg.per_dilation, n_classes, hop=hop)
    model = RocketClassifier(config)
    with torch.no_grad():
        model.transform.masks.copy_(torch.as_tensor(params.masks))
        model.transform.biases.copy_(torch.as_tensor(params.biases))
        if head is not None:
            scale, w, b, temperature = head
            model.scale.copy_(torch.as_tensor(scale))
            model.head.weight.copy_(torch.as_tensor(w))
            model.head.bias.copy_(torch.as_tensor(b))
            model.temperature.fill_(float(temperature))
    return model.eval()


def fit_rocket_classifier(
    windows: np.ndarray,
    y: np.ndarray,
    n_classes: int,
    *,
    unlabelled: np.ndarray | None = None,
    groups: np.ndarray | None = None,
    features: int = 10_000,
    seed: int = 0,
) -> RocketClassifier:
    """MiniRocket and a ridge head fitted on labelled ``windows (N, L, C)`` of terrains ``y (N,)``.

    Args:
        windows: Labelled windows, normalised samples, oldest first.
        y: Terrain index of each.
        n_classes: Terrains in all (some may have no window: they are never predicted).
        unlabelled: Windows the transform's biases are drawn from (any logs, no labels read); ``None``: ``windows``.
        groups: What each labelled window belongs to (a log, a labelled segment): the temperature is fitted on
            windows of groups the head did not see. ``None``: each window is its own group.
        features: MiniRocket features (a multiple of 84).
        seed: Seed of the transform's draws.

    Raises:
        ValueError: Fewer than two terrains among the labels, or windows shorter than 9 samples.
    """
    y = np.asarray(y, np.int64)
    if len(np.unique(y)) < 2:
        raise ValueError(f"a MiniRocket classifier needs windows of two terrains or more; got {len(np.unique(y))}")
    source = windows if unlabelled is None else unlabelled
    params = fit_rocket(on_grid(source).transpose(0, 2, 1), features=features, seed=seed)
    x = rocket_features(rocket_model(params, n_classes), windows)  # (N, F)
    scale = feature_scale(x)
    x *= scale
    w, b, alpha = ridge_head(x, y, n_classes)
    groups = np.arange(len(y)) if groups is None else np.asarray(groups)
    temperature = fit_temperature_nll(held_out_scores(x, y, groups, alpha, n_classes), y)
    return rocket_model(params, n_classes, head=(scale, w, b, temperature))
