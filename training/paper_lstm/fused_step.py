"""Both stages one sample at a time in NumPy, with the weights fused so a step is a handful of BLAS calls.

The streaming runtime's hot loop. A per-sample step of PyTorch modules spends most of its time dispatching small
operators (measured in ``benchmarks/speed/bench_streaming.py``); here every step is two matrix products per stage into
preallocated buffers and a few in-place ufuncs, with no allocation. The numbers are :class:`StepModel`'s (the ONNX
export) to float32 rounding.

Fusions, each exact up to rounding:
- stage 1 reads ``[z, h1]`` from one buffer against ``[W_ih; W_hh]``, so input and recurrence are one product;
- the gates are reordered to ``(i, f, o, g)`` and the ``i, f, o`` rows halved, so one ``tanh`` over all gates
  gives ``tanh(g)`` and, with a multiply-add on the first three quarters, ``σ(x) = (1 + tanh(x/2)) / 2``
  (NumPy's ``tanh`` is vectorised; SciPy's logistic took 5× as long on 4,000 gates);
- every ensemble member's input weights sit side by side: the members' input gates are one product;
- each stage's bias is a row of its weights against a constant 1 in the input buffer;
- with one member (a single deployed model), stage 2 reads ``[features, h2, 1]`` from one buffer as stage 1 does, and
  its softmax is the output: the ensemble's gather, bias and mean are skipped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..training_errors import BundleError

if TYPE_CHECKING:
    from ..runtime import ModelBundle


def _np(t) -> np.ndarray:
    return t.detach().cpu().numpy().astype(np.float32)


def _tanh_gates(w: np.ndarray) -> np.ndarray:
    """Last axis from ``(i, f, 2g, o)`` (:func:`fuse_weights`' layout) to ``(i/2, f/2, o/2, g)``, contiguous."""
    i, f, g2, o = np.split(w, 4, axis=-1)
    return 0.5 * np.concatenate([i, f, o, g2], axis=-1)


def _double_g(w: np.ndarray, hidden: int) -> np.ndarray:
    """Rows (or the last axis) of gates in PyTorch's order (i, f, g, o), with ``g`` doubled."""
    w = w.copy()
    w[..., 2 * hidden : 3 * hidden] *= 2.0
    return w


@dataclass(frozen=True)
class FusedWeights:
    """Both stages' weights laid out for a fused step (float32; ``g`` gate rows doubled)."""

    mode: str
    c: int
    h1: int
    m: int
    h2: int
    k: int
    mean: np.ndarray  # (C,)
    inv_std: np.ndarray  # (C,)
    w1: np.ndarray  # (C + H1, 4H1): [W_ih; W_hh] of stage 1, transposed
    b1: np.ndarray  # (4H1,)
    head_w: np.ndarray  # (H1, C)
    head_b: np.ndarray  # (C,)
    w2: np.ndarray  # (F, M·4H2): column block j is member j's input weights
    u2: np.ndarray  # (M, H2, 4H2)
    b2: np.ndarray  # (M, 4H2)
    out_w: np.ndarray  # (M, H2, K)
    out_b: np.ndarray  # (M, 1, K)


def fuse_weights(bundle: ModelBundle) -> FusedWeights:
    """The bundle's weights in the fused layout (raises ``BundleError`` without a classifier)."""
    if not bundle.classifiers:
        raise BundleError("the bundle has no classifier: train stage 2 first")
    p, cs = bundle.predictor, bundle.classifiers
    h1, h2 = p.config.hidden, cs[0].config.hidden
    w_ih, w_hh = _np(p.lstm.weight_ih_l0), _np(p.lstm.weight_hh_l0)  # (4H1, C), (4H1, H1)
    folded = [x.folded_input() for x in cs]  # stage 2's input standardisation in its weights
    return FusedWeights(
        mode=bundle.feature_mode,
        c=p.config.n_channels,
        h1=h1,
        m=len(cs),
        h2=h2,
        k=cs[0].config.n_classes,
        mean=bundle.normalizer.mean.astype(np.float32),
        inv_std=(1.0 / bundle.normalizer.std).astype(np.float32),
        w1=_double_g(np.concatenate([w_ih, w_hh], axis=1).T, h1).copy(),
        b1=_double_g(_np(p.lstm.bias_ih_l0 + p.lstm.bias_hh_l0), h1),
        head_w=_np(p.head.weight).T.copy(),
        head_b=_np(p.head.bias),
        w2=np.concatenate([_double_g(_np(w).T, h2) for w, _ in folded], axis=1),
        u2=np.stack([_double_g(_np(x.lstm.weight_hh_l0).T, h2) for x in cs]),
        b2=np.stack([_double_g(_np(b), h2) for _, b in folded]),
        out_w=np.stack([_np(x.head.weight).T for x in cs]),
        out_b=np.stack([_np(x.head.bias) for x in cs])[:, None, :],
    )


class FusedStep:
    """One step of both stages for ``streams`` streams; the state lives inside.

    Example:
        >>> step = FusedStep(bundle, streams=1)
        >>> probs = step(sample[None])   # (1, C) raw -> (1, K), a view valid until the next call
    """

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        w = fuse_weights(bundle)
        self.w = w  # fields copied onto self below: the hot path reads them once per step without an indirection
        self.mode, self.c, self.h1, self.m, self.h2, self.k, self.b = w.mode, w.c, w.h1, w.m, w.h2, w.k, streams
        self.mean, self.inv_std = w.mean, w.inv_std
        h2, m = w.h2, w.m
        # (C + H1 + 1, 4H1): the bias against the constant 1
        self.w1 = _tanh_gates(np.concatenate([w.w1, w.b1[None]]))
        self.head_w, self.head_b = w.head_w, w.head_b
        n_feats = self.n_feats = w.w2.shape[0]
        self.w2 = _tanh_gates(w.w2.reshape(n_feats, m, 4 * h2)).reshape(n_feats, m * 4 * h2)
        self.u2, self.b2 = _tanh_gates(w.u2), _tanh_gates(w.b2)
        self.out_w, self.out_b = w.out_w, w.out_b
        if m == 1:  # (F + H2 + 1, 4H2): input, recurrence and bias of the one member in one product
            self.w2_one = np.concatenate([self.w2, self.u2[0], self.b2])
        self._buffers()
        self.reset()

    def _buffers(self) -> None:
        b, c, h1, m, h2, k = self.b, self.c, self.h1, self.m, self.h2, self.k
        self.u1 = np.zeros((b, c + h1 + 1), np.float32)  # [z, h1, 1]: h1 is written in place for the next step
        self.z, self.h = self.u1[:, :c], self.u1[:, c : c + h1]
        self.c1 = np.zeros((b, h1), np.float32)
        self.g1 = np.empty((b, 4 * h1), np.float32)
        self.t1 = np.empty((b, h1), np.float32)
        self.prev = np.zeros((b, c), np.float32)  # stage 1's estimate of this sample, from the step before
        self.est = np.empty((b, c), np.float32)
        self.err = np.empty((b, c), np.float32)
        self.started = False
        self.g2in = np.empty((b, m * 4 * h2), np.float32)
        self.g2 = np.empty((m, b, 4 * h2), np.float32)
        self.c2 = np.zeros((m, b, h2), np.float32)
        self.t2 = np.empty((m, b, h2), np.float32)
        self.logits = np.empty((m, b, k), np.float32)
        self.probs = np.empty((b, k), np.float32)
        self.rowwise = np.empty((m, b, 1), np.float32)  # softmax's max and sum per member and stream
        if m == 1:
            nf = self.n_feats
            self.u2in = np.zeros((b, nf + h2 + 1), np.float32)  # [features, h2, 1]: h2 written in place
            self.hh2 = self.u2in[None, :, nf : nf + h2]  # (1, B, H2), a view
        else:
            self.hh2 = np.zeros((m, b, h2), np.float32)

    def reset(self) -> None:
        """Forget every stream's past."""
        for a in (self.u1, self.c1, self.prev, self.hh2, self.c2):
            a[...] = 0.0
        self.u1[:, -1] = 1.0
        if self.m == 1:
            self.u2in[:, -1] = 1.0
        self.started = False

    @staticmethod
    def _cell(g: np.ndarray, c: np.ndarray, h: np.ndarray, tmp: np.ndarray, hidden: int) -> None:
        """In place: gates ``g (..., 4H)`` (``(i/2, f/2, o/2, g)``, see :func:`_tanh_gates`) -> new ``c``, ``h``."""
        np.tanh(g, out=g)
        ifo = g[..., : 3 * hidden]
        ifo *= 0.5
        ifo += 0.5  # σ(x) = (1 + tanh(x/2)) / 2
        i, f = g[..., :hidden], g[..., hidden : 2 * hidden]
        o, gg = g[..., 2 * hidden : 3 * hidden], g[..., 3 * hidden :]
        c *= f
        np.multiply(i, gg, out=tmp)
        c += tmp
        np.tanh(c, out=tmp)
        np.multiply(o, tmp, out=h)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``(B, C)`` raw samples -> ``(B, K)`` ensemble-mean probabilities (a buffer overwritten by the next call)."""
        np.subtract(x, self.mean, out=self.z)
        self.z *= self.inv_std
        np.matmul(self.u1, self.w1, out=self.g1)  # (B, 4H1): input, recurrence and bias at once
        self._cell(self.g1, self.c1, self.h, self.t1, self.h1)
        if self.mode == "hidden":
            feats = self.h
        else:
            np.matmul(self.h, self.head_w, out=self.est)
            self.est += self.head_b  # (B, C): estimate of the next sample
            if self.started:
                np.subtract(self.z, self.prev, out=self.err)
            else:
                self.err[...] = 0.0  # no estimate yet at a stream's first sample, as offline
            self.prev[...] = self.est
            if self.mode.endswith("surprise"):
                np.abs(self.err, out=self.err)
            feats = {"estimate": self.est, "error": self.err, "surprise": self.err}.get(self.mode)
            if feats is None and self.m == 1:  # hidden+…: straight into stage 2's input buffer
                self.u2in[:, : self.h1] = self.h
                self.u2in[:, self.h1 : self.n_feats] = self.err
            elif feats is None:
                feats = np.concatenate([self.h, self.err], axis=1)
        self.started = True
        if self.m == 1:
            if feats is not None:
                self.u2in[:, : self.n_feats] = feats
            np.matmul(self.u2in, self.w2_one, out=self.g2[0])  # (B, 4H2): input, recurrence and bias at once
        else:
            np.matmul(feats, self.w2, out=self.g2in)  # (B, M·4H2): every member's input gates
            np.matmul(self.hh2, self.u2, out=self.g2)  # (M, B, 4H2)
            self.g2 += self.g2in.reshape(self.b, self.m, -1).transpose(1, 0, 2)
            self.g2 += self.b2[:, None, :]
        self._cell(self.g2, self.c2, self.hh2, self.t2, self.h2)
        np.matmul(self.hh2, self.out_w, out=self.logits)  # (M, B, K)
        self.logits += self.out_b
        lg, rw = self.logits, self.rowwise  # softmax in place, (M, B, K), without allocating
        np.max(lg, axis=-1, keepdims=True, out=rw)
        lg -= rw
        np.exp(lg, out=lg)
        np.sum(lg, axis=-1, keepdims=True, out=rw)
        lg /= rw
        if self.m == 1:
            return lg[0]
        np.mean(lg, axis=0, out=self.probs)
        return self.probs


class Bf16Step:
    """:class:`FusedStep`'s computation in PyTorch with bfloat16 weights, for many streams at once.

    With tens of robots a step is bound by arithmetic, not dispatch: 64 streams at the paper's sizes are ~230 MFLOP
    per step, and 64 × 500 Hz needs ~115 GFLOP/s, above one core's float32 peak on the CPUs here. bfloat16 products
    (AVX-512 BF16 through oneDNN) measured 1.7× float32's throughput for 64 streams; the cell's state and
    nonlinearities stay float32. Probabilities moved by up to ~1e-4 in the tests and the benchmark (reported beside
    the timing in ``benchmarks/speed/bench_streaming.py``).
    """

    def __init__(self, bundle: ModelBundle, *, streams: int = 1) -> None:
        import torch

        self.torch = torch
        self.streams = streams
        f = self.f = fuse_weights(bundle)
        bf = torch.bfloat16

        def t(a: np.ndarray, dtype=torch.float32):
            return torch.from_numpy(np.ascontiguousarray(a)).to(dtype)

        self.mean, self.inv_std = t(f.mean), t(f.inv_std)
        self.w1, self.b1 = t(f.w1, bf), t(f.b1)
        self.head_w, self.head_b = t(f.head_w), t(f.head_b)
        self.w2, self.u2, self.b2 = t(f.w2, bf), t(f.u2, bf), t(f.b2)[:, None, :]
        self.out_w, self.out_b = t(f.out_w), t(f.out_b)
        self.reset()

    def reset(self) -> None:
        """Forget every stream's past."""
        torch, f, b = self.torch, self.f, self.streams
        self.h1 = torch.zeros(b, f.h1)
        self.c1 = torch.zeros(b, f.h1)
        self.h2 = torch.zeros(f.m, b, f.h2)
        self.c2 = torch.zeros(f.m, b, f.h2)
        self.prev = torch.zeros(b, f.c)
        self.started = False

    @staticmethod
    def _cell(g, c, hidden: int):
        s = g.sigmoid()
        i, f, gg, o = s.split(hidden, dim=-1)
        c = f * c + i * (2.0 * gg - 1.0)
        return o * c.tanh(), c

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``(B, C)`` raw samples -> ``(B, K)`` ensemble-mean probabilities."""
        torch, f = self.torch, self.f
        bf = torch.bfloat16
        with torch.inference_mode():
            z = (torch.from_numpy(np.asarray(x, np.float32)) - self.mean) * self.inv_std  # (B, C)
            g1 = (torch.cat([z, self.h1], dim=1).to(bf) @ self.w1).float() + self.b1  # (B, 4H1)
            self.h1, self.c1 = self._cell(g1, self.c1, f.h1)
            if f.mode == "hidden":
                feats = self.h1
            else:
                est = self.h1 @ self.head_w + self.head_b  # (B, C)
                err = z - self.prev if self.started else torch.zeros_like(z)
                self.prev = est
                if f.mode.endswith("surprise"):
                    err = err.abs()
                feats = {"estimate": est, "error": err, "surprise": err}.get(f.mode)
                if feats is None:
                    feats = torch.cat([self.h1, err], dim=1)
            self.started = True
            g2 = (feats.to(bf) @ self.w2).float().view(self.streams, f.m, -1).transpose(0, 1)  # (M, B, 4H2)
            g2 = g2 + torch.bmm(self.h2.to(bf), self.u2).float() + self.b2
            self.h2, self.c2 = self._cell(g2, self.c2, f.h2)
            logits = torch.bmm(self.h2, self.out_w) + self.out_b  # (M, B, K)
            return logits.softmax(-1).mean(0).numpy()
