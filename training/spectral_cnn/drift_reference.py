"""What the drift score compares a frame with (:class:`DriftReference`), and the score from a member's two views of
its rows in NumPy: what :mod:`.window_drift` fits and scores in PyTorch, here without it, so that a bundle scores log
files with NumPy alone (:mod:`.frame_numpy`, ``workbench classify``).

Each member's distance in a view is the mean Euclidean distance of a row to its ``neighbours`` nearest reference rows,
divided by the member's scale for that view; the larger view counts (:func:`scaled_drift`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

DRIFT_NEIGHBOURS = 5
DRIFT_QUANTILE = 0.95
DRIFTED = 1.0  # a step above this is called drifted
QUERY_CHUNK = 2048  # frames per distance block: QUERY_CHUNK × reference rows floats at a time
VIEWS = ("embedding", "inputs")
INPUT_MARGIN = 2.0  # the inputs' view counts from twice its held-out quantile: it catches what is far off, no more


@dataclass(frozen=True)
class DriftReference:
    """What the drift score compares a frame with.

    Attributes:
        references: Per ensemble member, ``(N_m, E)`` embeddings of labelled frames it trained on.
        inputs: Per member, ``(N_m, F)`` the same frames' window-mean standardised inputs.
        scales: ``(M, 2)`` per member, the divisor of each view's neighbour distance (embedding, inputs).
        neighbours: Nearest reference rows averaged.
        quantile: The held-out quantile that scores 1.
    """

    references: tuple[np.ndarray, ...]
    inputs: tuple[np.ndarray, ...]
    scales: np.ndarray
    neighbours: int = DRIFT_NEIGHBOURS
    quantile: float = DRIFT_QUANTILE

    def arrays(self) -> dict[str, np.ndarray]:
        """As named arrays for a safetensors file."""
        out = {}
        for i, (r, x) in enumerate(zip(self.references, self.inputs, strict=True)):
            out[f"member{i}.reference"] = np.ascontiguousarray(r, np.float32)
            out[f"member{i}.inputs"] = np.ascontiguousarray(x, np.float32)
        out["scales"] = np.asarray(self.scales, np.float32)
        return out

    def settings(self) -> dict:
        """The JSON-able settings stored beside the arrays."""
        return {"neighbours": self.neighbours, "quantile": self.quantile, "members": len(self.references)}

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray], settings: dict) -> DriftReference:
        """Rebuild from :meth:`arrays` and :meth:`settings`.

        Raises:
            ValueError: The arrays do not match the settings.
        """
        members = int(settings["members"])
        refs = tuple(np.asarray(arrays[f"member{i}.reference"], np.float32) for i in range(members))
        inputs = tuple(np.asarray(arrays[f"member{i}.inputs"], np.float32) for i in range(members))
        scales = np.asarray(arrays["scales"], np.float32)
        shapes_ok = all(r.ndim == 2 and x.ndim == 2 and len(r) == len(x) > 0 for r, x in zip(refs, inputs, strict=True))
        if scales.shape != (members, len(VIEWS)) or not shapes_ok or not (scales > 0).all():
            raise ValueError("the drift reference's arrays do not match its settings")
        return cls(refs, inputs, scales, int(settings["neighbours"]), float(settings["quantile"]))


def nearest_distance(reference: np.ndarray, queries: np.ndarray, neighbours: int) -> np.ndarray:
    """Mean Euclidean distance of each query ``(N, E)`` to its ``neighbours`` nearest rows of ``reference`` ``(R, E)``,
    ``QUERY_CHUNK`` queries at a time: the arithmetic of :func:`.window_drift.neighbour_distance` (squared norms less
    twice the products, clamped at 0) with NumPy's partition for PyTorch's ``topk``."""
    k = min(neighbours, len(reference))
    ref = np.ascontiguousarray(reference, np.float32)  # (R, E)
    ref_sq = np.square(ref).sum(axis=1)  # (R,)
    out = np.empty(len(queries), np.float32)
    for c in range(0, len(queries), QUERY_CHUNK):
        q = np.ascontiguousarray(queries[c : c + QUERY_CHUNK], np.float32)  # (n, E)
        sq = q @ ref.T  # (n, R) no (n, R, E)
        sq *= np.float32(-2.0)
        sq += np.square(q).sum(axis=1)[:, None]
        sq += ref_sq[None]
        near = np.partition(sq, k - 1, axis=1)[:, :k] if k < sq.shape[1] else sq  # (n, k) the nearest, unordered
        out[c : c + QUERY_CHUNK] = np.sqrt(np.maximum(near, 0.0)).mean(axis=1)
    return out


Distance = Callable[[np.ndarray, np.ndarray, int], np.ndarray]


def scaled_drift(
    reference: DriftReference, m: int, views: tuple[np.ndarray, np.ndarray], *, distance: Distance = nearest_distance
) -> np.ndarray:
    """Drift ``(N,)`` of rows as member ``m`` alone scores them, from their two views (unit embeddings ``(N, E)``,
    window-mean standardised inputs ``(N, F)``): each view's neighbour distance over its scale, the larger.
    ``distance``: how the nearest rows are found (PyTorch's where a session scores, NumPy's here)."""
    refs = (reference.references[m], reference.inputs[m])
    dist = np.stack([distance(r, v, reference.neighbours) for r, v in zip(refs, views, strict=True)], axis=1)  # (N, 2)
    return (dist / reference.scales[m]).max(axis=1)
