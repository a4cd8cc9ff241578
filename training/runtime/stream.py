"""Both stages one sample at a time, for the robot: the same numbers as the offline pass over a whole log.

:class:`StreamingClassifier` runs the step of whichever family the bundle holds (``registry.Family.stream_step``):
each family computes it in NumPy with weights prepared once (the paper family's fused LSTM cells, the default
family's frame products), which is what a robot's loop wants: no operator dispatch per sample, no allocation. The
ONNX export traces the same step written as a PyTorch module (``Family.step_module``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..training_errors import BundleError
from .bundle import ModelBundle
from .terrain_filter import FLOOR, TerrainFilter


class StreamingClassifier:
    """Class probabilities one sample at a time for ``streams`` independent streams (robots), state carried.

    Runs the bundle's family's NumPy step: the same numbers as the offline pass and the exported ONNX step,
    several times faster per sample than stepping PyTorch modules.

    Example:
        >>> clf = StreamingClassifier(load_bundle("bundle"))
        >>> for sample in imu_and_force_samples:      # (C,) raw values in bundle.channels order
        ...     probs = clf.step(sample)             # (K,) in bundle.classes order
    """

    def __init__(
        self,
        bundle: ModelBundle,
        *,
        streams: int = 1,
        precision: str = "float32",
        members: int | None = None,
        smooth_s: float | None = None,
    ) -> None:
        """
        Args:
            bundle: A bundle with a trained classifier.
            streams: Independent streams stepped together (one row each).
            precision: ``float32`` (the offline pass's numbers) or, for the paper family, ``bfloat16`` products:
                1.7× the throughput for 64 streams at once on CPUs with AVX-512 BF16 (measured), probabilities within
                ~1e-4.
            members: Run only the first this many of the k fold models (all when ``None``). A step reads every
                member's weights, so one member is about 2.5× faster per sample
                (``benchmarks/speed/bench_streaming.py``).
                The bundle's out-of-fold accuracy is single fold models' accuracy on data they did not see, so it
                is what one member is expected to reach; the ensemble's mean is usually a little better.
            smooth_s: The causal HMM filter (:class:`.terrain_filter.TerrainFilter`) over each stream's
                probabilities, for a robot that stays this many seconds on a terrain on average; off when ``None``.
                It answers a change late: ``self.filter.delay_steps(confidence)`` says by how many steps.
        """
        if not bundle.classifiers:
            raise BundleError("the bundle has no classifier: train stage 2 first")
        family = bundle.stage2_family()
        if precision not in family.precisions:
            choices = " or ".join(family.precisions)
            raise ValueError(f"precision must be {choices} for the {family.name} family, not {precision!r}")
        if members is not None:
            if not 1 <= members <= len(bundle.classifiers):
                raise ValueError(f"members must be 1 to {len(bundle.classifiers)}, not {members}")
            bundle = replace(bundle, classifiers=bundle.classifiers[:members])
        self.bundle = bundle
        self.streams = streams
        self._step = family.stream_step(bundle, streams=streams, precision=precision)
        k = len(bundle.classes)
        self.filter = None if smooth_s is None else TerrainFilter.for_dwell(smooth_s, bundle.rate_hz, k)
        self._belief = np.full((streams, k), 1.0 / k)  # (B, K) the filter's state per stream

    def reset(self) -> None:
        """Forget every stream's past (a new log, a robot restarted)."""
        self._step.reset()
        self._belief[:] = 1.0 / self._belief.shape[1]

    def step(self, x: np.ndarray) -> np.ndarray:
        """One raw sample per stream: ``(C,)`` -> ``(K,)`` or ``(B, C)`` -> ``(B, K)``."""
        x = np.asarray(x, np.float32)
        probs = self._step(x.reshape(1, -1) if x.ndim == 1 else x)  # (B, K)
        if self.filter is not None:
            belief = self.filter.transition(self._belief) * np.maximum(probs, FLOOR)  # (B, K)
            self._belief = belief / belief.sum(axis=1, keepdims=True)
            probs = self._belief.astype(np.float32)
        return probs[0].copy() if x.ndim == 1 else probs.copy()

    def run(self, samples: np.ndarray) -> np.ndarray:
        """A whole ``(T, C)`` log of one stream, step by step: ``(T, K)``."""
        return np.stack([self.step(s) for s in samples])
