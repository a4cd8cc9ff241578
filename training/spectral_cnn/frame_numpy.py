"""The default family's ensemble over a log's frames in NumPy: what scores log files without loading PyTorch.

``workbench classify`` of a short run spent most of its time importing PyTorch (3.5 s of 7.8 on two cores), for a
network of some 30 k weights per member that NumPy runs as fast. :class:`NumpyMembers` holds the members' weights as
arrays (read from a bundle's safetensors by :mod:`training.runtime.scoring_bundle`) and runs each member once per
frame as :func:`.frame_scores.frame_chunks` does in PyTorch: the same operations in the same order, so the
probabilities and the drift agree to float32 rounding (tested to 1e-5, the same most probable class).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .drift_reference import QUERY_CHUNK, DriftReference, scaled_drift
from .spectra import SpectralSteps, last_frame, window_index

SPREAD_EPS = 1e-6  # added to the pooled variance: a window of identical frames (a log's start) has none
STANDARDISATION = ("in_mean", "in_scale")  # absent from bundles saved before it: the identity


@dataclass(frozen=True, eq=False)
class FrameChunk:
    """The members' answers for frames ``[start, start + n)`` of one log.

    Attributes:
        start: First frame.
        probs: ``(M, n, K)`` float32 each member's class probabilities.
        drift: ``(n,)`` float32 the members' mean drift (:mod:`.window_drift`), or ``None`` without a reference.
    """

    start: int
    probs: np.ndarray
    drift: np.ndarray | None


def step_frames(steps: SpectralSteps) -> np.ndarray:
    """``(T,)`` the frame each step of the log reads last (``-1`` before the first frame completes)."""
    return last_frame(np.arange(len(steps), dtype=np.int64), steps.config)


class NumpyMembers:
    """The ``M`` window classifiers of a bundle as float32 arrays, run over a log's frames.

    Each member's state holds the module's own names (:meth:`weight_shapes`; :data:`STANDARDISATION` only where the
    bundle has it): ``mix.weight (H, F, 1)``, ``conv.weight (H, H, 3)``, ``head.weight (K, 2H)`` and their biases.
    """

    optional = STANDARDISATION

    def __init__(self, states: Sequence[Mapping[str, np.ndarray]], *, window: int) -> None:
        """
        Args:
            states: Per member, its weights by name (checked for shape by the caller that read them).
            window: Frames per step (the classifier config's ``window``).
        """
        if not states:
            raise ValueError("no ensemble member")
        self.window = window
        f = states[0]["mix.weight"].shape[1]
        self.mean = [np.asarray(s.get("in_mean", np.zeros(f)), np.float32) for s in states]  # (F,) each
        self.scale = [np.asarray(s.get("in_scale", np.ones(f)), np.float32) for s in states]  # (F,) each
        self.mix = [np.ascontiguousarray(s["mix.weight"][:, :, 0].T, np.float32) for s in states]  # (F, H)
        self.mix_b = [np.asarray(s["mix.bias"], np.float32) for s in states]  # (H,)
        # (H, 3H): a frame times each tap (in, tap·out)
        taps = [np.asarray(s["conv.weight"], np.float32).transpose(1, 2, 0) for s in states]  # (H, 3, H) in, tap, out
        self.conv = [np.ascontiguousarray(t.reshape(t.shape[0], -1)) for t in taps]
        self.conv_b = [np.asarray(s["conv.bias"], np.float32) for s in states]  # (H,)
        self.head = [np.ascontiguousarray(s["head.weight"].T, np.float32) for s in states]  # (2H, K)
        self.head_b = [np.asarray(s["head.bias"], np.float32) for s in states]  # (K,)

    @staticmethod
    def weight_shapes(*, frame_width: int, hidden: int, n_classes: int) -> dict[str, tuple[int, ...]]:
        """Each weight's shape in a member of these sizes (the module's state dict; the standardisation's two may be
        absent: :data:`STANDARDISATION`)."""
        f, h, k = frame_width, hidden, n_classes
        return {
            "in_mean": (f,),
            "in_scale": (f,),
            "mix.weight": (h, f, 1),
            "mix.bias": (h,),
            "conv.weight": (h, h, 3),
            "conv.bias": (h,),
            "head.weight": (k, 2 * h),
            "head.bias": (k,),
        }

    def __len__(self) -> int:
        return len(self.mix)

    @property
    def n_classes(self) -> int:
        return self.head[0].shape[1]

    def chunks(
        self, steps: SpectralSteps, *, drift: DriftReference | None = None, chunk: int = QUERY_CHUNK
    ) -> Iterator[FrameChunk]:
        """Every member over every frame of one log, ``chunk`` frames at a time (as ``frame_chunks``).

        Args:
            steps: The log's stage-2 inputs (its frames are read a chunk at a time).
            drift: The bundle's drift reference: each frame's drift from the same pooled features.
            chunk: Frames per pass.
        """
        n = len(steps.frames)
        for c in range(0, n, chunk):
            idx = np.arange(c, min(c + chunk, n))
            lo = max(c - self.window + 1, 0)
            block = np.array(steps.frames[lo : int(idx[-1]) + 1], np.float32)  # (b, F) a copy
            window = window_index(idx - lo, self.window)  # (n, W) each frame's window as indices into the block
            probs, total = self._members(block, window, drift)
            yield FrameChunk(c, probs, total)

    def blank(self) -> np.ndarray:
        """``(M, K)`` each member's probabilities for a step before the log's first frame completes (zeros in)."""
        zero = np.zeros((1, self.mix[0].shape[0]), np.float32)  # (1, F)
        probs, _ = self._members(zero, np.zeros((1, self.window), np.int64), None)  # (M, 1, K)
        return probs[:, 0]

    def _members(
        self, block: np.ndarray, window: np.ndarray, drift: DriftReference | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """``(M, n, K)`` probabilities and ``(n,)`` mean drift of the windows ``window (n, W)`` of ``block (b, F)``."""
        n = len(window)
        probs = np.empty((len(self), n, self.n_classes), np.float32)
        total = np.zeros(n, np.float32) if drift is not None else None
        for m in range(len(self)):
            standard = (block - self.mean[m]) * self.scale[m]  # (b, F)
            mixed = gelu_tanh(standard @ self.mix[m] + self.mix_b[m])  # (b, H) once per frame
            # each frame times each of the 3-frame convolution's taps, once, then summed at each window position from
            # the frames before and after it (zero beyond the window's ends, as the module's padding)
            taps = (mixed @ self.conv[m]).reshape(len(block), 3, -1)  # (b, 3, H)
            conved = taps[window, 1]  # (n, W, H)
            conved[:, 1:] += taps[window[:, :-1], 0]
            conved[:, :-1] += taps[window[:, 1:], 2]
            conved += self.conv_b[m]
            conved = gelu_tanh(conved)  # (n, W, H)
            mean = conved.mean(axis=1)  # (n, H)
            std = np.sqrt(np.square(conved - mean[:, None]).mean(axis=1) + np.float32(SPREAD_EPS))  # (n, H)
            pooled = np.concatenate([mean, std], axis=1)  # (n, 2H)
            logits = pooled @ self.head[m] + self.head_b[m]  # (n, K)
            logits -= logits.max(axis=1, keepdims=True)
            e = np.exp(logits)
            probs[m] = e / e.sum(axis=1, keepdims=True)
            if drift is not None and total is not None:
                unit = pooled / np.maximum(np.linalg.norm(pooled, axis=1, keepdims=True), np.float32(1e-12))
                total += scaled_drift(drift, m, (unit, standard[window].mean(axis=1)))  # (n,)
        return probs, None if total is None else total / len(self)


def gelu_tanh(x: np.ndarray) -> np.ndarray:
    """PyTorch's ``gelu(x, approximate="tanh")`` in NumPy, float32, in one scratch array (the streaming step calls it
    on small arrays, where each temporary costs as much as the arithmetic)."""
    out = x * x
    out *= x
    out *= np.float32(0.044715)
    out += x
    out *= np.float32(0.7978845608028654)
    np.tanh(out, out=out)
    out += np.float32(1.0)
    out *= x
    out *= np.float32(0.5)
    return out
