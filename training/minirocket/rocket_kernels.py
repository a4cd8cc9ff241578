"""MiniRocket's fixed kernels and what its fit chooses: dilations, channel combinations and biases (NumPy).

MiniRocket (Dempster, Schmidt and Webb, KDD 2021) convolves a window with 84 fixed kernels of 9 taps (weight -1,
and 2 at three taps: every choice of 3 of the 9), each at a few dilations and summed over a random subset of the
channels, and pools each output into the proportion of positions above a bias (PPV). Its fit draws the channel
subsets and takes the biases as quantiles of the convolution of a random training window.

This follows aeon's ``MiniRocket`` (1.6.0, after the authors' code) step for step, so that the same parameters give
the same features: ``tests/training/test_rocket_transform.py`` checks it against numbers aeon computed
(``benchmarks/minirocket_aeon_golden.py``). It is written here, not imported, because aeon's numba kernels neither
stream nor export to ONNX, and aeon 1.6 pins NumPy below the version this project runs; the random draws use
NumPy's ``Generator``, so only the parameters aeon drew (not its seed) reproduce its features.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

TAPS = 9
KERNELS = 84
KERNEL_TAPS = np.asarray(list(combinations(range(TAPS), 3)), np.int64)  # (84, 3): the taps of weight 2
GOLDEN = (np.sqrt(5) + 1) / 2
# The classifier's inputs are rounded to 1/1024 of a standard deviation and held within ±64 of them: every product
# and sum in the convolutions (weights -1 and 2, at most 9 channels: |sum| < 2^13) is then a multiple of 2^-10 under
# 2^23, exact in float32, so PyTorch, ONNX Runtime and any other order of sums give the same features. Without it,
# a sum within rounding of a bias falls on either side, and the exported step differed from PyTorch by 2.6e-4.
GRID = 1024.0
CLIP = 64.0


def on_grid(x: np.ndarray) -> np.ndarray:
    """``x`` held within ±:data:`CLIP` and rounded to multiples of 1 / :data:`GRID` (float32, half to even)."""
    return np.round(np.clip(np.asarray(x, np.float32), -CLIP, CLIP) * np.float32(GRID)) / np.float32(GRID)


@dataclass(frozen=True)
class RocketConfig:
    """What a fitted MiniRocket transform is, besides its arrays.

    Attributes:
        length: Samples per window.
        channels: Channels per sample.
        dilations: The dilations, ascending.
        per_dilation: Features per kernel at each dilation (``features = 84 · sum(per_dilation)``).
    """

    length: int
    channels: int
    dilations: tuple[int, ...]
    per_dilation: tuple[int, ...]

    @property
    def features(self) -> int:
        """Features per window."""
        return KERNELS * sum(self.per_dilation)


@dataclass(frozen=True)
class RocketParameters:
    """A fitted transform: its config, each (dilation, kernel) combination's channels as a 0/1 mask
    ``(D, 84, C)``, and one bias per feature ``(F,)`` in the features' order (dilation, kernel, quantile)."""

    config: RocketConfig
    masks: np.ndarray
    biases: np.ndarray


def fit_dilations(length: int, features: int, max_dilations: int) -> tuple[np.ndarray, np.ndarray]:
    """The dilations for windows of ``length`` samples and how many features each kernel gets at each: dilations
    spread exponentially up to the one whose kernel spans the window."""
    per_kernel = features // KERNELS
    true_max = min(per_kernel, max_dilations)
    multiplier = per_kernel / true_max
    max_exponent = np.log2((length - 1) / (TAPS - 1))
    dilations, counts = np.unique(np.logspace(0, max_exponent, true_max, base=2).astype(np.int32), return_counts=True)
    counts = (counts * multiplier).astype(np.int32)
    remainder, i = per_kernel - int(counts.sum()), 0
    while remainder > 0:
        counts[i] += 1
        remainder -= 1
        i = (i + 1) % len(counts)
    return dilations.astype(np.int64), counts.astype(np.int64)


def rocket_quantiles(n: int) -> np.ndarray:
    """The first ``n`` terms of the golden-ratio low-discrepancy sequence: which quantile each feature's bias is."""
    return np.asarray([(i * GOLDEN) % 1 for i in range(1, n + 1)], np.float32)


def kernel_outputs(window: np.ndarray, dilation: int, kernels: np.ndarray | slice = slice(None)) -> np.ndarray:
    """The ``kernels``' convolutions (default: all 84) of one window ``(C, L)`` at ``dilation``, zeros beyond the
    ends: ``(K, C, L)``.

    The sums run in aeon's order (the centre tap, then the taps before it, then after), so that float32 rounding
    matches its numbers and a bias quantile sits where aeon's does.
    """
    c, n = window.shape
    a, g = -window, window + window + window
    alpha = a.copy()
    gamma = np.zeros((TAPS, c, n), np.float32)
    gamma[TAPS // 2] = g
    end = n - (TAPS - 1) * dilation // 2
    for tap in range(TAPS // 2):
        alpha[:, -end:] = alpha[:, -end:] + a[:, :end]
        gamma[tap, :, -end:] = g[:, :end]
        end += dilation
    start = dilation
    for tap in range(TAPS // 2 + 1, TAPS):
        alpha[:, :-start] = alpha[:, :-start] + a[:, start:]
        gamma[tap, :, :-start] = g[:, start:]
        start += dilation
    t = KERNEL_TAPS[kernels]
    return alpha[None] + gamma[t[:, 0]] + gamma[t[:, 1]] + gamma[t[:, 2]]  # (K, C, L)


def fit_rocket(
    windows: np.ndarray, *, features: int = 10_000, max_dilations: int = 32, seed: int = 0
) -> RocketParameters:
    """Fit MiniRocket to ``windows`` ``(N, C, L)``: dilations from the length, a random channel subset per
    (dilation, kernel), and biases from quantiles of its convolution of a random window.

    Args:
        windows: The windows the biases are drawn from (any of the logs: no labels are read).
        features: Features wanted; rounded down to a multiple of 84 (aeon's ``n_kernels``).
        max_dilations: Most dilations per kernel.
        seed: Seed of the draws.

    Raises:
        ValueError: Windows shorter than a kernel (9 samples), or none.
    """
    x = np.asarray(windows, np.float32)
    if x.ndim != 3 or len(x) == 0 or x.shape[2] < TAPS:
        raise ValueError(f"MiniRocket needs windows (N, C, L) with N >= 1 and L >= {TAPS}; got {x.shape}")
    rng = np.random.default_rng(seed)
    n, c, length = x.shape
    dilations, per_dilation = fit_dilations(length, max(features, KERNELS), max_dilations)
    quantiles = rocket_quantiles(KERNELS * int(per_dilation.sum()))
    most = min(c, 9)
    sizes = (2 ** rng.uniform(0, np.log2(most + 1), (len(dilations), KERNELS))).astype(np.int64)
    masks = np.zeros((len(dilations), KERNELS, c), np.float32)
    biases = np.zeros(len(quantiles), np.float32)
    f0 = 0
    for d, (dilation, nf) in enumerate(zip(dilations.tolist(), per_dilation.tolist(), strict=True)):
        for k in range(KERNELS):
            chosen = rng.choice(c, sizes[d, k], replace=False)
            masks[d, k, chosen] = 1.0
            window = x[rng.integers(n)][np.sort(chosen)]
            out = kernel_outputs(window, dilation, np.asarray([k]))[0].sum(0)  # (L,)
            biases[f0 : f0 + nf] = np.quantile(out, quantiles[f0 : f0 + nf])
            f0 += nf
    config = RocketConfig(length, c, tuple(dilations.tolist()), tuple(per_dilation.tolist()))
    return RocketParameters(config, masks, biases)


def aeon_parameters(parameters: tuple[np.ndarray, ...], *, length: int, channels: int) -> RocketParameters:
    """Our form of the ``parameters`` a fitted aeon ``MiniRocket`` holds (channels per combination, their
    indices, dilations, features per dilation, biases): how the tests load aeon's fit."""
    per_combination, indices, dilations, per_dilation, biases = parameters
    masks = np.zeros((len(dilations) * KERNELS, channels), np.float32)
    starts = np.concatenate([[0], np.cumsum(per_combination)])
    for i in range(len(per_combination)):
        masks[i, indices[starts[i] : starts[i + 1]]] = 1.0
    config = RocketConfig(length, channels, tuple(int(d) for d in dilations), tuple(int(n) for n in per_dilation))
    return RocketParameters(config, masks.reshape(len(dilations), KERNELS, channels), np.asarray(biases, np.float32))
