"""Both stages one sample at a time, for the robot: the same numbers as the offline pass over a whole log.

The paper family is below; the default family's step is :mod:`training.window_step`, and
:class:`StreamingClassifier` runs whichever the bundle holds.

:class:`StepModel` is the one-step computation in PyTorch (stage-1 LSTM cell, features, every ensemble member's LSTM
cell, mean probabilities); the ONNX export is that module, traced. :class:`StreamingClassifier`, the runtime, computes
the same step with fused weights in NumPy (:mod:`training.fused_step`), which is what a robot's loop wants: no
operator dispatch per sample, no allocation.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch
from torch import nn

from .bundle import ModelBundle
from .fused_step import Bf16Step, FusedStep
from .models import stage1_features
from .training_errors import BundleError
from .window_step import WindowStep


def _cell(x: torch.Tensor, h: torch.Tensor, c: torch.Tensor, w_ih, w_hh, b) -> tuple[torch.Tensor, torch.Tensor]:
    """One LSTM step, PyTorch's gate order (i, f, g, o). ``x (B, F)``, ``h, c (B, H)``."""
    gates = x @ w_ih.T + h @ w_hh.T + b  # (B, 4H)
    i, f, g, o = gates.chunk(4, dim=-1)
    c = torch.sigmoid(f) * c + torch.sigmoid(i) * torch.tanh(g)
    return torch.sigmoid(o) * torch.tanh(c), c


class StepModel(nn.Module):
    """One step of both stages for ``B`` streams; states are explicit inputs and outputs.

    Inputs: ``x (B, C)`` raw sample, ``h1, c1 (B, H1)``, ``h2, c2 (M, B, H2)``, ``prev (B, C)`` stage 1's estimate
    of this sample from the step before (zeros at a stream's start, meaning "no estimate yet").
    Outputs: ``probs (B, K)`` ensemble mean, then the new ``h1, c1, h2, c2, prev``.
    """

    def __init__(self, bundle: ModelBundle) -> None:
        super().__init__()
        if not bundle.classifiers:
            raise BundleError("the bundle has no classifier: train stage 2 first")
        p = bundle.predictor
        self.mode = bundle.feature_mode
        self.register_buffer("mean", torch.from_numpy(bundle.normalizer.mean))
        self.register_buffer("std", torch.from_numpy(bundle.normalizer.std))
        self.register_buffer("w1_ih", p.lstm.weight_ih_l0.detach().clone())
        self.register_buffer("w1_hh", p.lstm.weight_hh_l0.detach().clone())
        self.register_buffer("b1", (p.lstm.bias_ih_l0 + p.lstm.bias_hh_l0).detach().clone())
        self.register_buffer("head_w", p.head.weight.detach().clone())
        self.register_buffer("head_b", p.head.bias.detach().clone())
        cs = bundle.classifiers
        folded = [m.folded_input() for m in cs]  # input standardisation folded into the weights
        self.register_buffer("w2_ih", torch.stack([w for w, _ in folded]))  # (M, 4H, F)
        self.register_buffer("w2_hh", torch.stack([m.lstm.weight_hh_l0.detach() for m in cs]))  # (M, 4H, H)
        self.register_buffer("b2", torch.stack([b for _, b in folded]))  # (M, 4H)
        self.register_buffer("out_w", torch.stack([m.head.weight.detach() for m in cs]))  # (M, K, H)
        self.register_buffer("out_b", torch.stack([m.head.bias.detach() for m in cs]))  # (M, K)

    def forward(self, x, h1, c1, h2, c2, prev, started):
        z = (x - self.mean) / self.std  # (B, C)
        h1, c1 = _cell(z, h1, c1, self.w1_ih, self.w1_hh, self.b1)
        estimate = h1 @ self.head_w.T + self.head_b  # (B, C): estimate of the next sample
        error = (z - prev) * started  # (B, C): zero at a stream's first sample, as offline
        feats = stage1_features(self.mode, h1, estimate, error)  # (B, F): the offline pass's features, one step
        gates = torch.einsum("bf,mgf->mbg", feats, self.w2_ih) + torch.einsum("mbh,mgh->mbg", h2, self.w2_hh)
        gates = gates + self.b2[:, None, :]  # (M, B, 4H)
        i, f, g, o = gates.chunk(4, dim=-1)
        c2 = torch.sigmoid(f) * c2 + torch.sigmoid(i) * torch.tanh(g)
        h2 = torch.sigmoid(o) * torch.tanh(c2)  # (M, B, H)
        logits = torch.einsum("mbh,mkh->mbk", h2, self.out_w) + self.out_b[:, None, :]
        probs = torch.softmax(logits, dim=-1).mean(dim=0)  # (B, K)
        return probs, h1, c1, h2, c2, estimate


class StreamingClassifier:
    """Class probabilities one sample at a time for ``streams`` independent streams (robots), state carried.

    Runs :class:`~training.fused_step.FusedStep` (NumPy, fused weights): the same numbers as :class:`StepModel`
    and the offline pass, several times faster per sample than stepping PyTorch modules.

    Example:
        >>> clf = StreamingClassifier(load_bundle("bundle"))
        >>> for sample in imu_and_force_samples:      # (C,) raw values in bundle.channels order
        ...     probs = clf.step(sample)             # (K,) in bundle.classes order
    """

    def __init__(
        self, bundle: ModelBundle, *, streams: int = 1, precision: str = "float32", members: int | None = None
    ) -> None:
        """
        Args:
            bundle: A bundle with a trained classifier.
            streams: Independent streams stepped together (one row each).
            precision: ``float32`` (the offline pass's numbers) or ``bfloat16`` products: 1.7× the throughput for
                64 streams at once on CPUs with AVX-512 BF16 (measured), probabilities within ~1e-4.
            members: Run only the first this many of the k fold models (all when ``None``). A step reads every
                member's weights, so one member is about 2.5× faster per sample (``benchmarks/bench_streaming.py``).
                The bundle's out-of-fold accuracy is single fold models' accuracy on data they did not see, so it
                is what one member is expected to reach; the ensemble's mean is usually a little better.
        """
        if precision not in ("float32", "bfloat16"):
            raise ValueError(f"precision must be float32 or bfloat16, not {precision!r}")
        if precision != "float32" and bundle.family == "default":
            raise ValueError("the default family streams in float32 only (its step is a frame's products every hop)")
        if members is not None:
            if not 1 <= members <= len(bundle.classifiers):
                raise ValueError(f"members must be 1 to {len(bundle.classifiers)}, not {members}")
            bundle = replace(bundle, classifiers=bundle.classifiers[:members])
        self.bundle = bundle
        self.streams = streams
        if bundle.family == "default":
            self._step = WindowStep(bundle, streams=streams)
        elif precision == "float32":
            self._step = FusedStep(bundle, streams=streams)
        else:
            self._step = Bf16Step(bundle, streams=streams)

    def reset(self) -> None:
        """Forget every stream's past (a new log, a robot restarted)."""
        self._step.reset()

    def step(self, x: np.ndarray) -> np.ndarray:
        """One raw sample per stream: ``(C,)`` -> ``(K,)`` or ``(B, C)`` -> ``(B, K)``."""
        x = np.asarray(x, np.float32)
        if x.ndim == 1:
            return self._step(x.reshape(1, -1))[0].copy()
        return self._step(x).copy()

    def run(self, samples: np.ndarray) -> np.ndarray:
        """A whole ``(T, C)`` log of one stream, step by step: ``(T, K)``."""
        return np.stack([self.step(s) for s in samples])
