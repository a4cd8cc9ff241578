"""The default family one sample at a time: the same numbers as the offline pass (front end, the last frames, the
window network), for the robot.

:class:`WindowStep` is the NumPy runtime :class:`~training.StreamingClassifier` runs: a frame completes every
``hop`` samples and only then do the spectra and the ensemble's networks run; between frames a step returns the last
probabilities. A stream's first frame fills its whole window, as ``spectra.stacked_frames`` pads a log's start.

:class:`WindowStepModel` is the same step in PyTorch for the ONNX export, with its
state explicit (the last ``frame`` samples and the last ``window`` frames of each stream) and the spectra as products
with fixed cosine and sine tables, so the ONNX graph needs no FFT operator.
"""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING

import numpy as np
import torch
from torch import nn

from ..training_errors import BundleError
from .frame_numpy import SPREAD_EPS, gelu_tanh
from .spectra import SpectralConfig, SpectralStream

if TYPE_CHECKING:
    from ..runtime import ModelBundle

INPUTS = ("x", "ring", "count", "frames", "n_frames")
OUTPUTS = ("probs", "ring_out", "count_out", "frames_out", "n_frames_out")


def _front_end(bundle: ModelBundle) -> SpectralConfig:
    if bundle.spectral is None or not bundle.classifiers:
        raise BundleError("the bundle has no trained default-family classifier: train stage 2 first")
    return bundle.spectral


class WindowStep:
    """The default family's step for ``streams`` streams: ``(B, C)`` raw samples in, ``(B, K)`` probabilities out.

    A frame's step is the one that costs (every ``hop`` samples; the p99 of a stream's latency), so it computes only
    what the new frame changes. The members' weights are stacked: a few NumPy calls for the whole ensemble, not a
    few per member. Each frame is mixed (the 1x1 convolution) and multiplied by the 3-frame convolution's three
    taps once, when it arrives; those products are kept while the frame stays in the window. When the window moves
    by a frame, the convolution's outputs inside it keep their inputs, so only the first position (its left
    neighbour is now padding) and the last two (the new frame) are summed again
    (``benchmarks/speed/bench_streaming.py``).
    """

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        self.config = cfg = _front_end(bundle)
        self.normalizer = bundle.normalizer
        ws = [m.arrays() for m in bundle.classifiers]
        self.m, self.h = len(ws), ws[0]["mix_b"].shape[0]
        self.k = len(bundle.classes)
        self.mix = np.concatenate([w["mix"] for w in ws], axis=1)  # (F, M·H)
        self.mix_b = np.concatenate([w["mix_b"] for w in ws])  # (M·H,)
        self.taps = np.stack([np.concatenate(list(w["conv"]), axis=1) for w in ws])  # (M, H, 3H) (in, tap·out)
        self.conv_b = np.stack([w["conv_b"] for w in ws])[:, None, None, :]  # (M, 1, 1, H)
        self.head = np.stack([w["head"] for w in ws])  # (M, 2H, K)
        self.head_b = np.stack([w["head_b"] for w in ws])[:, None, :]  # (M, 1, K)
        self.front = SpectralStream(cfg, len(bundle.channels), streams=streams)
        w = cfg.window
        # each stream's last `window` frames, mixed, times each tap of the convolution, with zero rows at both ends
        # (the convolution's padding); and the convolution's outputs after its GELU at each position of the window
        self.prods = np.zeros((self.m, streams, w + 2, 3, self.h), np.float32)  # (M, B, W + 2, taps, H)
        self.conved = np.zeros((self.m, streams, w, self.h), np.float32)  # (M, B, W, H)
        self.n_frames = 0  # frames seen by every stream
        self.probs = np.empty((streams, self.k), np.float32)
        self.reset()

    def reset(self) -> None:
        """Forget every stream's past."""
        self.front.reset()
        self.n_frames = 0
        zero = self._products(np.zeros((1, self.mix.shape[0]), np.float32))  # (M, 1, 3, H) an all-zero frame
        self.prods[:] = 0.0
        self.prods[:, :, 1:-1] = zero[:, :, None]
        self._convolve(0, self.config.window)
        self.probs[:] = self._probs()

    def _products(self, feats: np.ndarray) -> np.ndarray:
        """New frames ``(d, F)`` mixed and multiplied by each tap: ``(M, d, 3, H)``."""
        mixed = gelu_tanh(feats @ self.mix + self.mix_b)  # (d, M·H)
        mixed = mixed.reshape(len(feats), self.m, self.h).transpose(1, 0, 2)  # (M, d, H)
        return np.matmul(mixed, self.taps).reshape(self.m, len(feats), 3, self.h)

    def _convolve(self, lo: int, hi: int) -> None:
        """The convolution and its GELU at positions ``[lo, hi)`` of every window, kept in ``conved``. Position j
        reads padded rows j, j + 1 and j + 2 through taps 0, 1 and 2: slices, no gathers."""
        p = self.prods  # (M, B, W + 2, 3, H)
        c = p[:, :, lo:hi, 0] + p[:, :, lo + 1 : hi + 1, 1]  # (M, B, hi - lo, H)
        c += p[:, :, lo + 2 : hi + 2, 2]
        c += self.conv_b
        self.conved[:, :, lo:hi] = gelu_tanh(c)

    def _moved(self) -> None:
        """After the windows moved by a frame: the convolution at position 0 (its left neighbour is padding now)
        and at the last two (the new frame), in one pass (a GELU is nine NumPy calls)."""
        w, p = self.config.window, self.prods  # (M, B, W + 2, 3, H)
        if w < 3:
            self._convolve(0, w)
            return
        c = np.empty((self.m, p.shape[1], 3, self.h), np.float32)  # positions 0, W - 2, W - 1
        np.add(p[:, :, 1, 1], p[:, :, 2, 2], out=c[:, :, 0])  # padded row 0 is zeros
        np.add(p[:, :, w - 2 : w, 0], p[:, :, w - 1 : w + 1, 1], out=c[:, :, 1:])
        c[:, :, 1:] += p[:, :, w : w + 2, 2]
        c += self.conv_b
        g = gelu_tanh(c)
        self.conved[:, :, 0] = g[:, :, 0]
        self.conved[:, :, w - 2 :] = g[:, :, 1:]

    def _probs(self) -> np.ndarray:
        """The ensemble's mean probabilities from the convolved windows: ``(B, K)``."""
        h = self.conved  # (M, B, W, H)
        w = np.float32(h.shape[2])
        # divided, as torch's mean is: a small spread amplifies the last bit of the mean (a product by 1/W differs)
        mean = h.sum(axis=2) / w  # (M, B, H)
        dev = h - mean[:, :, None, :]
        # the spread from deviations, as the module: E[h²] - E[h]² cancels to noise at a stream's start
        spread = np.sqrt(np.einsum("mbwh,mbwh->mbh", dev, dev) / w + SPREAD_EPS)
        logits = np.matmul(np.concatenate([mean, spread], axis=2), self.head)  # (M, B, K)
        logits += self.head_b
        e = np.exp(logits - logits.max(axis=2, keepdims=True))
        return (e / e.sum(axis=2, keepdims=True)).mean(axis=0)  # (B, K)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        # the offline pass's normalisation to the bit: a frame's small spectra amplify an input's last bit
        feats, _ = self.front.step(self.normalizer(x))  # (B, F) last complete frame
        # streams move in step (a call gives each a sample; reset() resets all), so they complete frames together
        if self.front.completed[0]:
            new = self._products(feats)  # (M, B, 3, H)
            if self.n_frames == 0:  # the first frame fills the window: every position anew
                self.prods[:, :, 1:-1] = new[:, :, None]
                self._convolve(0, self.config.window)
            else:
                self.prods[:, :, 1:-2] = self.prods[:, :, 2:-1]
                self.prods[:, :, -2] = new
                self.conved[:, :, 1:-2] = self.conved[:, :, 2:-1]  # same inputs, one position earlier
                self._moved()
            self.n_frames += 1
            self.probs[:] = self._probs()
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
        """``(B, L, C)`` -> ``(B, F)``, as ``spectra.frame_features``."""
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


def zero_state(bundle: ModelBundle, streams: int = 1) -> dict[str, np.ndarray]:
    """The inputs of a stream's first step, apart from ``x``."""
    cfg = _front_end(bundle)
    z = np.zeros
    return {
        "ring": z((streams, cfg.frame, len(bundle.channels)), np.float32),
        "count": z((streams, 1), np.float32),
        "frames": z((streams, cfg.window, cfg.width), np.float32),
        "n_frames": z((streams, 1), np.float32),
    }
