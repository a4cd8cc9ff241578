"""The MiniRocket family one sample at a time: a ring of the last ``length`` normalised samples, classified every
``hop`` samples; between hops a step returns the last probabilities (the offline pass's ``RawSteps`` repeat the
last hop's window the same way).

:class:`RocketStep` is what :class:`~training.StreamingClassifier` runs: the ring in NumPy, the transform and heads
through the same PyTorch modules as the offline pass (the transform's comparisons with its biases make any other
order of sums differ by a position now and then), once per hop. The members share one transform: its features
are computed once and every head reads them. :class:`RocketStepModel` is the step for the ONNX export, its state
explicit; it classifies only the streams at a hop.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..training_errors import BundleError
from .rocket_classifier import RocketClassifier, shares_transform

if TYPE_CHECKING:
    from ..runtime import ModelBundle

INPUTS = ("x", "ring", "count", "probs_in")
OUTPUTS = ("probs", "ring_out", "count_out", "probs_out")


def _members(bundle: ModelBundle) -> list[RocketClassifier]:
    members = [m for m in bundle.classifiers if isinstance(m, RocketClassifier)]
    if not members or len(members) != len(bundle.classifiers):
        raise BundleError("the bundle has no trained MiniRocket classifier: train stage 2 first")
    return members


def ensemble_probs(members: list[RocketClassifier], windows: torch.Tensor, *, shared: bool) -> torch.Tensor:
    """The members' mean probabilities of ``windows (B, L·C)``: ``(B, K)``; the transform once when they share it
    (:func:`shares_transform`, decided once by the caller, not at every hop)."""
    if not shared:
        return torch.stack([torch.softmax(m.logits(windows), -1) for m in members]).mean(0)
    feats = members[0].transformed(windows)  # (B, F) the shared transform's, once
    return torch.stack([torch.softmax(m.head_logits(feats), -1) for m in members]).mean(0)


class RocketStep:
    """The family's step for ``streams`` streams: ``(B, C)`` raw samples in, ``(B, K)`` probabilities out."""

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        self.members = _members(bundle)
        self.shared = shares_transform(self.members)
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
        windows = torch.from_numpy(self.ring.reshape(len(self.ring), -1))
        return ensemble_probs(self.members, windows, shared=self.shared).numpy()

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
    ``count (B, 1)`` samples seen; ``probs (B, K)`` the last probabilities (at a stream's start those of an all-zero
    window, as the offline pass gives before a log's first hop: ``zero_state``). Outputs: ``probs (B, K)``, then the
    new ``ring, count`` and ``probs`` again as the next state.

    Only the streams at a hop are classified: their rows are gathered, so between hops the transform runs on no row
    at all and a call costs the ring's shift (a graph has no branch to skip it with).
    """

    def __init__(self, bundle: ModelBundle) -> None:
        super().__init__()
        self.members = nn.ModuleList(_members(bundle))
        self.shared = shares_transform(list(self.members))
        cfg = self.members[0].config
        self.hop = cfg.hop
        self.register_buffer("mean", torch.from_numpy(bundle.normalizer.mean))
        self.register_buffer("std", torch.from_numpy(bundle.normalizer.std))

    def forward(self, x, ring, count, probs):
        z = (x - self.mean) / self.std  # (B, C)
        ring = torch.cat([ring[:, 1:], z[:, None]], dim=1)  # (B, L, C)
        count = count + 1.0
        at_hop = torch.nonzero(torch.remainder(count[:, 0], self.hop) == 0)[:, 0]  # (H,) streams at a hop
        new = ensemble_probs(list(self.members), ring.index_select(0, at_hop).flatten(1), shared=self.shared)  # (H, K)
        probs = probs.index_copy(0, at_hop, new)
        return probs, ring, count, probs


def zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``: an empty ring, and the probabilities of its window."""
    members = _members(bundle)
    cfg = members[0].config
    ring = np.zeros((streams, cfg.length, cfg.channels), np.float32)
    with torch.inference_mode():
        zero = torch.zeros(1, cfg.length * cfg.channels)
        probs = ensemble_probs(members, zero, shared=shares_transform(members)).numpy()  # (1, K)
    return {"ring": ring, "count": np.zeros((streams, 1), np.float32), "probs_in": np.repeat(probs, streams, 0)}
