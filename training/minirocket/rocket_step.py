"""The MiniRocket family one sample at a time: a ring of the last ``length`` normalised samples, classified every
``hop`` samples; between hops a step returns the last probabilities (the offline pass's ``RawSteps`` repeat the
last hop's window the same way).

:class:`RocketStep` is what :class:`~training.StreamingClassifier` runs: the ring in NumPy, the transform and heads
through the same PyTorch modules as the offline pass (the transform's comparisons with its biases make any other
order of sums differ by a position now and then), once per hop. The members share one transform: its features
are computed once and every head reads them. :class:`RocketStepModel` is the step for the ONNX export, its state
explicit; it classifies the window held as of the last hop at every call.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..training_errors import BundleError
from .rocket_classifier import RocketClassifier

if TYPE_CHECKING:
    from ..runtime import ModelBundle

INPUTS = ("x", "ring", "count", "window")
OUTPUTS = ("probs", "ring_out", "count_out", "window_out")


def _members(bundle: ModelBundle) -> list[RocketClassifier]:
    members = [m for m in bundle.classifiers if isinstance(m, RocketClassifier)]
    if not members or len(members) != len(bundle.classifiers):
        raise BundleError("the bundle has no trained MiniRocket classifier: train stage 2 first")
    return members


def ensemble_probs(members: list[RocketClassifier], windows: torch.Tensor) -> torch.Tensor:
    """The members' mean probabilities of ``windows (B, L·C)``: ``(B, K)``; one transform when they share it."""
    shared = all(torch.equal(m.transform.biases, members[0].transform.biases) for m in members[1:])
    if not shared:
        return torch.stack([torch.softmax(m.logits(windows), -1) for m in members]).mean(0)
    feats = members[0].transformed(windows)  # (B, F) the shared transform's, once
    return torch.stack([torch.softmax(m.head(feats * m.scale) / m.temperature, -1) for m in members]).mean(0)


class RocketStep:
    """The family's step for ``streams`` streams: ``(B, C)`` raw samples in, ``(B, K)`` probabilities out."""

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        self.members = _members(bundle)
        cfg = self.members[0].config
        self.length, self.hop, self.channels = cfg.length, cfg.hop, cfg.channels
        self.normalizer = bundle.normalizer
        self.ring = np.zeros((streams, cfg.length, cfg.channels), np.float32)  # (B, L, C) oldest first
        self.count = 0
        self.probs = np.empty((streams, cfg.n_classes), np.float32)
        self.reset()

    def reset(self) -> None:
        """Forget every stream's past: the ring is zeros, as a log's start is in the offline pass."""
        self.ring[:] = 0.0
        self.count = 0
        self.probs[:] = self._classify()

    @torch.inference_mode()
    def _classify(self) -> np.ndarray:
        return ensemble_probs(self.members, torch.from_numpy(self.ring.reshape(len(self.ring), -1))).numpy()

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.ring[:, :-1] = self.ring[:, 1:]
        self.ring[:, -1] = self.normalizer(x)
        self.count += 1
        if self.count % self.hop == 0:  # streams move in step: they reach a hop together
            self.probs[:] = self._classify()
        return self.probs


class RocketStepModel(nn.Module):
    """One step of the MiniRocket family for ``B`` streams, for the ONNX export; states are explicit.

    Inputs: ``x (B, C)`` raw sample; ``ring (B, L, C)`` the last ``length`` normalised samples, oldest first;
    ``count (B, 1)`` samples seen; ``window (B, L, C)`` the ring as of the last hop. All zeros at a stream's start.
    Outputs: ``probs (B, K)`` the ensemble's mean for ``window``, then the new ``ring, count, window``.
    """

    def __init__(self, bundle: ModelBundle) -> None:
        super().__init__()
        self.members = nn.ModuleList(_members(bundle))
        cfg = self.members[0].config
        self.hop = cfg.hop
        self.register_buffer("mean", torch.from_numpy(bundle.normalizer.mean))
        self.register_buffer("std", torch.from_numpy(bundle.normalizer.std))

    def forward(self, x, ring, count, window):
        z = (x - self.mean) / self.std  # (B, C)
        ring = torch.cat([ring[:, 1:], z[:, None]], dim=1)  # (B, L, C)
        count = count + 1.0
        done = torch.remainder(count, self.hop) == 0  # (B, 1)
        window = torch.where(done[:, :, None], ring, window)
        probs = ensemble_probs(list(self.members), window.flatten(1))  # (B, K)
        return probs, ring, count, window


def zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``."""
    cfg = _members(bundle)[0].config
    ring = np.zeros((streams, cfg.length, cfg.channels), np.float32)
    return {"ring": ring, "count": np.zeros((streams, 1), np.float32), "window": ring.copy()}
