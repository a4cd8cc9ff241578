"""The default family one sample at a time: the same numbers as the offline pass (front end, window summary,
linear softmax), for the robot.

:class:`WindowStep` is the NumPy runtime :class:`~training.stream.StreamingClassifier` runs: a frame completes every
``hop`` samples and only then do the spectra, the summary and the ensemble's products run; between frames a step
returns the last probabilities. :class:`WindowStepModel` is the same step in PyTorch for the ONNX export, with its
state explicit (the last ``frame`` samples and the last ``window`` frames of each stream) and the spectra as products
with fixed cosine and sine tables, so the ONNX graph needs no FFT operator.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from .bundle import ModelBundle
from .spectral import SpectralConfig, SpectralStream
from .training_errors import BundleError


def _front_end(bundle: ModelBundle) -> SpectralConfig:
    if bundle.spectral is None or not bundle.classifiers:
        raise BundleError("the bundle has no trained default-family classifier: train stage 2 first")
    return bundle.spectral


class WindowStep:
    """The default family's step for ``streams`` streams: ``(B, C)`` raw samples in, ``(B, K)`` probabilities out."""

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        self.config = cfg = _front_end(bundle)
        self.mean, self.inv_std = bundle.normalizer.mean, 1.0 / bundle.normalizer.std
        folded = [m.folded() for m in bundle.classifiers]
        self.w = np.concatenate([w for w, _ in folded], axis=1)  # (F, M·K): every member in one product
        self.b = np.concatenate([b for _, b in folded])  # (M·K,)
        self.m, self.k = len(folded), len(bundle.classes)
        self.front = SpectralStream(cfg, len(bundle.channels), streams=streams)
        self.frames = np.zeros((streams, cfg.window, cfg.width), np.float64)  # (B, W, F) ring of the last frames
        self.n_frames = np.zeros(streams, np.int64)
        self.probs = np.empty((streams, self.k), np.float32)
        self.reset()

    def reset(self) -> None:
        """Forget every stream's past."""
        self.front.reset()
        self.frames[:] = 0.0
        self.n_frames[:] = 0
        self.probs[:] = self._probs(np.zeros((len(self.probs), self.config.summary_width), np.float32))

    def _probs(self, summary: np.ndarray) -> np.ndarray:
        logits = (summary @ self.w + self.b).reshape(len(summary), self.m, self.k)  # (B, M, K)
        logits -= logits.max(axis=2, keepdims=True)
        e = np.exp(logits)
        return (e / e.sum(axis=2, keepdims=True)).mean(axis=1).astype(np.float32)  # (B, K)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        feats, _ = self.front.step((x - self.mean) * self.inv_std)  # (B, F) last complete frame
        cfg = self.config
        for b in np.flatnonzero(self.front.completed):
            self.frames[b, self.n_frames[b] % cfg.window] = feats[b]
            self.n_frames[b] += 1
            held = self.frames[b, : min(int(self.n_frames[b]), cfg.window)]  # (n, F) the frames in the window
            summary = np.concatenate([held.mean(0), held.std(0)]).astype(np.float32)[None]  # (1, 2F)
            self.probs[b] = self._probs(summary)[0]
        return self.probs


class WindowStepModel(nn.Module):
    """One step of the default family for ``B`` streams, for the ONNX export; states are explicit.

    Inputs: ``x (B, C)`` raw sample; ``ring (B, L, C)`` the last ``frame`` normalised samples, oldest first;
    ``count (B, 1)`` samples seen; ``frames (B, W, F)`` the last ``window`` frames' features, oldest first;
    ``n_frames (B, 1)`` frames seen. All zeros at a stream's start.
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
        folded = [m.folded() for m in bundle.classifiers]
        self.register_buffer("w", torch.from_numpy(np.stack([w for w, _ in folded])))  # (M, F2, K)
        self.register_buffer("b", torch.from_numpy(np.stack([b for _, b in folded])))  # (M, K)

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
        shifted = torch.cat([frames[:, 1:], self._frame(ring)[:, None]], dim=1)  # (B, W, F)
        frames = torch.where(done[:, :, None], shifted, frames)
        n_frames = n_frames + done.float()
        n = n_frames.clamp(max=cfg.window)  # (B, 1) frames in the window
        slots = torch.arange(cfg.window, dtype=x.dtype, device=x.device)[None, :]  # (1, W)
        held = (slots >= cfg.window - n).float()[:, :, None]  # (B, W, 1): the newest n frames
        denom = n.clamp(min=1.0)[:, :, None]
        mean = (frames * held).sum(dim=1, keepdim=True) / denom  # (B, 1, F)
        var = ((frames - mean).pow(2) * held).sum(dim=1) / denom[:, 0]  # (B, F)
        summary = torch.cat([mean[:, 0], var.sqrt()], dim=1)  # (B, 2F)
        logits = torch.einsum("bf,mfk->mbk", summary, self.w) + self.b[:, None, :]  # (M, B, K)
        probs = torch.softmax(logits, dim=-1).mean(dim=0)  # (B, K)
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
