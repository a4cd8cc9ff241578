"""The default family one sample at a time: the same numbers as the offline pass (front end, the last frames, the
window network), for the robot.

:class:`WindowStep` is the NumPy runtime :class:`~training.stream.StreamingClassifier` runs: a frame completes every
``hop`` samples and only then do the spectra and the ensemble's networks run; between frames a step returns the last
probabilities. A stream's first frame fills its whole window, as ``spectral.stacked_frames`` pads a log's start.

:class:`WindowStepModel` is the same step in PyTorch for the ONNX export, with its
state explicit (the last ``frame`` samples and the last ``window`` frames of each stream) and the spectra as products
with fixed cosine and sine tables, so the ONNX graph needs no FFT operator.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn

from .bundle import ModelBundle
from .spectral import SpectralConfig, SpectralStream
from .training_errors import BundleError
from .window_classifier import window_logits


def _front_end(bundle: ModelBundle) -> SpectralConfig:
    if bundle.spectral is None or not bundle.classifiers:
        raise BundleError("the bundle has no trained default-family classifier: train stage 2 first")
    return bundle.spectral


class WindowStep:
    """The default family's step for ``streams`` streams: ``(B, C)`` raw samples in, ``(B, K)`` probabilities out."""

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        self.config = cfg = _front_end(bundle)
        self.mean, self.inv_std = bundle.normalizer.mean, 1.0 / bundle.normalizer.std
        self.members = [m.arrays() for m in bundle.classifiers]
        self.k = len(bundle.classes)
        self.front = SpectralStream(cfg, len(bundle.channels), streams=streams)
        self.frames = np.zeros((streams, cfg.window, cfg.width), np.float32)  # (B, W, F) the last frames, oldest first
        self.n_frames = np.zeros(streams, np.int64)
        self.probs = np.empty((streams, self.k), np.float32)
        self.reset()

    def reset(self) -> None:
        """Forget every stream's past."""
        self.front.reset()
        self.frames[:] = 0.0
        self.n_frames[:] = 0
        self.probs[:] = self._probs(self.frames)

    def _probs(self, frames: np.ndarray) -> np.ndarray:
        """``(B, W, F)`` -> ``(B, K)``: the members' softmax, averaged."""
        out = np.zeros((len(frames), self.k), np.float32)
        for w in self.members:
            logits = window_logits(w, frames)  # (B, K)
            e = np.exp(logits - logits.max(axis=1, keepdims=True))
            out += e / e.sum(axis=1, keepdims=True)
        return out / len(self.members)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        feats, _ = self.front.step((x - self.mean) * self.inv_std)  # (B, F) last complete frame
        done = np.flatnonzero(self.front.completed)
        if len(done):
            first = done[self.n_frames[done] == 0]
            self.frames[first] = feats[first, None, :]  # a stream's first frame fills its window
            self.frames[done] = np.concatenate([self.frames[done, 1:], feats[done, None, :]], axis=1)
            self.n_frames[done] += 1
            self.probs[done] = self._probs(self.frames[done])
        return self.probs


class WindowStepModel(nn.Module):
    """One step of the default family for ``B`` streams, for the ONNX export; states are explicit.

    Inputs: ``x (B, C)`` raw sample; ``ring (B, L, C)`` the last ``frame`` normalised samples, oldest first;
    ``count (B, 1)`` samples seen; ``frames (B, W, F)`` the last ``window`` frames' features, oldest first (a
    stream's first frame fills all of them); ``n_frames (B, 1)`` frames seen. All zeros at a stream's start.
    Outputs: ``probs (B, K)`` ensemble mean, then the new ``ring, count, frames, n_frames``.
    """

    def __init__(self, bundle: ModelBundle) -> None:
        super().__init__()
        cfg = self.config = _front_end(bundle)
        self.register_buffer("mean", torch.from_numpy(bundle.normalizer.mean))
        self.register_buffer("std", torch.from_numpy(bundle.normalizer.std))
        n = torch.arange(cfg.frame, dtype=torch.float64)
        k = torch.arange(cfg.bins, dtype=torch.float64)
        angle = 2 * torch.pi * n[:, None] * k[None, :] / cfg.frame  # (L, bins)
        window = torch.from_numpy(np.hamming(cfg.frame))[:, None]
        self.register_buffer("cos", (window * torch.cos(angle)).float())  # the Hamming window folded in
        self.register_buffer("sin", (window * torch.sin(angle)).float())
        self.register_buffer("fast", torch.as_tensor(cfg.fast, dtype=torch.long))
        self.register_buffer("slow", torch.as_tensor(cfg.slow, dtype=torch.long))
        self.members = nn.ModuleList(copy.deepcopy(m).eval() for m in bundle.classifiers)

    def _frame(self, ring: torch.Tensor) -> torch.Tensor:
        """``(B, L, C)`` -> ``(B, F)``, as ``spectral.frame_features``."""
        cfg, parts = self.config, []
        if cfg.fast:
            seg = ring.index_select(2, self.fast)  # (B, L, Cf)
            if cfg.detrend:
                seg = seg - seg.mean(dim=1, keepdim=True)
            re = torch.einsum("blc,lk->bck", seg, self.cos)  # (B, Cf, bins)
            im = torch.einsum("blc,lk->bck", seg, self.sin)
            parts.append(torch.log(re * re + im * im + cfg.eps).flatten(1))
        if cfg.slow:
            seg = ring.index_select(2, self.slow)  # (B, L, Cs)
            mean = seg.mean(dim=1)
            std = (seg - mean[:, None]).pow(2).mean(dim=1).sqrt()
            stats = torch.stack([mean, std, seg.amin(dim=1), seg.amax(dim=1)], dim=2)  # (B, Cs, 4)
            parts.append(stats.flatten(1))
        return torch.cat(parts, dim=1)

    def forward(self, x, ring, count, frames, n_frames):
        cfg = self.config
        z = (x - self.mean) / self.std  # (B, C)
        ring = torch.cat([ring[:, 1:], z[:, None]], dim=1)  # (B, L, C)
        count = count + 1.0
        done = (count >= cfg.frame) & (torch.remainder(count - cfg.frame, cfg.hop) == 0)  # (B, 1)
        new = self._frame(ring)[:, None]  # (B, 1, F)
        shifted = torch.cat([frames[:, 1:], new], dim=1)  # (B, W, F)
        shifted = torch.where(n_frames[:, :, None] == 0, new.expand_as(frames), shifted)  # the first fills all
        frames = torch.where(done[:, :, None], shifted, frames)
        n_frames = n_frames + done.float()
        flat = frames.flatten(1)  # (B, W·F)
        probs = torch.stack([torch.softmax(m.logits(flat), dim=-1) for m in self.members]).mean(dim=0)  # (B, K)
        return probs, ring, count, frames, n_frames


def window_zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``."""
    cfg = _front_end(bundle)
    z = np.zeros
    return {
        "ring": z((streams, cfg.frame, len(bundle.channels)), np.float32),
        "count": z((streams, 1), np.float32),
        "frames": z((streams, cfg.window, cfg.width), np.float32),
        "n_frames": z((streams, 1), np.float32),
    }
