"""Highlight tracks: per-timestep acquisition scores, smoothed, normalised per session, cut into intervals.

Every function takes and returns NumPy arrays. Shapes: ``T`` timesteps of one log, ``K`` classes, ``M`` ensemble
members.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

Kind = Literal["surprise", "entropy", "margin", "disagreement", "drift"]
KINDS: tuple[Kind, ...] = ("surprise", "entropy", "margin", "disagreement", "drift")
DRIFT_TRACK_AT_1 = 0.9  # the drift track's value where the drift score is 1 (the line past which a step is drifted)
_EPS = 1e-12


@dataclass(frozen=True)
class LogScores:
    """The model's per-timestep scores of one log, as ``labeling`` needs them.

    Attributes:
        surprise: ``(T,)`` stage-1 prediction error (any non-negative scale).
        probs: ``(T, K)`` ensemble-mean class probabilities, or ``None`` before a classifier exists.
        disagreement: ``(T,)`` ensemble mutual information (BALD), or ``None``.
        drift: ``(T,)`` how unlike the labelled data each step is (1: as far as the farthest 5 % of held-out
            labelled time), or ``None`` when the model gives none.
        agreement: ``(T,)`` the share of the members' pairs that name the same terrain (:func:`member_agreement`),
            or ``None`` (fewer than two members, or scores kept before it existed).
    """

    surprise: np.ndarray
    probs: np.ndarray | None = None
    disagreement: np.ndarray | None = None
    drift: np.ndarray | None = None
    agreement: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.surprise)

    @property
    def entropy(self) -> np.ndarray | None:
        """``(T,)`` predictive entropy of ``probs`` in nats, or ``None`` before a classifier exists."""
        return None if self.probs is None else entropy(self.probs)

    @property
    def predicted(self) -> np.ndarray | None:
        """``(T,)`` index of the most probable class, or ``None`` before a classifier exists."""
        return None if self.probs is None else np.asarray(self.probs).argmax(axis=-1)

    def raw(self, kind: Kind) -> np.ndarray | None:
        """``(T,)`` the unsmoothed track of ``kind``; higher is more worth labelling. ``None`` when unavailable."""
        if kind == "surprise":
            return np.asarray(self.surprise, np.float64)
        if kind == "disagreement":
            return None if self.disagreement is None else np.asarray(self.disagreement, np.float64)
        if kind == "drift":
            return None if self.drift is None else np.asarray(self.drift, np.float64)
        if self.probs is None:
            return None
        return self.entropy if kind == "entropy" else margin_uncertainty(self.probs)


@dataclass(frozen=True)
class Interval:
    """A highlighted stretch ``[start, stop)`` of one log, in samples; ``score`` is its peak normalised score."""

    log: int
    start: int
    stop: int
    score: float
    kind: Kind


def entropy(probs: np.ndarray) -> np.ndarray:
    """Predictive entropy in nats: ``(T, K)`` -> ``(T,)``."""
    p = np.clip(np.asarray(probs, np.float64), _EPS, 1.0)
    return -(p * np.log(p)).sum(axis=-1)


def margin_uncertainty(probs: np.ndarray) -> np.ndarray:
    """One minus the gap between the two most probable classes: ``(T, K)`` -> ``(T,)`` in ``[0, 1]``.

    1 where the top two classes tie, 0 where one class has all the mass.
    """
    p = np.asarray(probs, np.float64)
    if p.shape[-1] < 2:
        return np.zeros(p.shape[:-1])
    top2 = np.partition(p, -2, axis=-1)[..., -2:]  # (T, 2): second, first
    return 1.0 - (top2[..., 1] - top2[..., 0])


def mutual_information(member_probs: np.ndarray) -> np.ndarray:
    """BALD disagreement of an ensemble: ``(M, T, K)`` -> ``(T,)``, entropy of the mean minus mean entropy."""
    mean = member_probs.mean(axis=0)
    return np.maximum(entropy(mean) - np.mean([entropy(m) for m in member_probs], axis=0), 0.0)


def member_agreement(member_probs: np.ndarray) -> np.ndarray:
    """``(M, T, K)`` -> ``(T,)``: the share of the ``M (M - 1) / 2`` pairs of members whose most probable class is
    the same. Its mean over a file estimates a member's accuracy there without a label (two networks trained apart
    disagree about as often as each errs: Jiang et al., ICLR 2022); ``M`` under 2 gives ones."""
    m, _, k = member_probs.shape
    if m < 2:
        return np.ones(member_probs.shape[1])
    top = np.asarray(member_probs).argmax(axis=-1)  # (M, T)
    same = np.zeros(top.shape[1])
    for c in range(k):
        n = (top == c).sum(axis=0)  # (T,) members naming c
        same += n * (n - 1)
    return same / (m * (m - 1))


def smooth(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average over ``window`` samples, shrinking at the ends: ``(T,)`` -> ``(T,)``."""
    x = np.asarray(x, np.float64)
    n = len(x)
    if window <= 1 or n == 0:
        return x.copy()
    c = np.concatenate([[0.0], np.cumsum(x)])  # (T + 1,)
    half = window // 2
    out = np.empty(n)
    # the full windows by slicing (no (T,) index arrays: hours of log), then the shrinking ones at the ends
    first, last = half, n - window + half  # steps whose window [t - half, t - half + window) fits
    if last >= first:
        out[first : last + 1] = (c[window : n + 1] - c[: n - window + 1]) / window
    ends = np.r_[np.arange(0, min(first, n)), np.arange(max(last + 1, first, 0), n)]
    lo = np.clip(ends - half, 0, n)
    hi = np.clip(ends - half + window, 0, n)
    out[ends] = (c[hi] - c[lo]) / (hi - lo)
    return out


def session_normaliser(tracks: Sequence[np.ndarray], *, max_reference: int = 200_000, seed: int = 0):
    """A function mapping a track's values to their rank in the whole session, in ``[0, 1]``.

    Ranks make kinds on different scales (nats, squared error) comparable, and make a threshold mean "the top
    ``1 - threshold`` of this session's time". At most ``max_reference`` values (a seeded sample) are kept.
    """
    total = sum(np.size(t) for t in tracks)
    if total == 0:
        ref = np.zeros(1)
    elif total <= max_reference:
        ref = np.concatenate([np.asarray(t, np.float64).ravel() for t in tracks])
    else:
        # a seeded sample drawn track by track, in proportion to length: hours of tracks are never concatenated
        rng = np.random.default_rng(seed)
        parts = []
        for t in tracks:
            flat = np.asarray(t).ravel()
            parts.append(flat[rng.integers(0, len(flat), max(1, round(max_reference * len(flat) / total)))])
        ref = np.concatenate(parts).astype(np.float64)
    ref = np.sort(ref)

    def normalise(x: np.ndarray) -> np.ndarray:
        # mid-rank: ties (a flat track) land in the middle, not at the top; the right edge is searched only where x
        # equals a reference value (the second search over every step was a tenth of a 10-hour rescoring)
        lo = np.searchsorted(ref, x, side="left")
        hi = lo.copy()
        tied = ref[np.minimum(lo, len(ref) - 1)] == x
        hi[tied] = np.searchsorted(ref, np.asarray(x)[tied], side="right")
        return (lo + hi) / (2.0 * len(ref))

    return normalise


def drift_track(drift: np.ndarray) -> np.ndarray:
    """A drift score (``≥ 0``, 1 at the drifted line) as a track in ``[0, 1)``: ``1 − 10^−d``, so 1 lands at
    ``DRIFT_TRACK_AT_1`` (the default highlight threshold) and 2 at 0.99.

    Drift keeps its own scale instead of the session's ranks: "unlike anything labelled" is a fact about the labels,
    and a session with nothing drifted highlights nothing.
    """
    return (1.0 - np.power(10.0, -np.maximum(np.asarray(drift, np.float64), 0.0))).astype(np.float32)


def drifted_share(drift: np.ndarray | None) -> float | None:
    """The share of steps whose drift score is above 1 (``None`` without a score)."""
    if drift is None or len(drift) == 0:
        return None
    return float(np.mean(np.asarray(drift) > 1.0))


def normalised_tracks(
    scores: Sequence[LogScores], *, window: int = 25, kinds: Sequence[Kind] = KINDS
) -> list[dict[Kind, np.ndarray]]:
    """Each available kind of each log, smoothed over ``window`` samples and ranked across the session (drift:
    on its own scale, :func:`drift_track`).

    Returns:
        Per log, ``kind -> (T,)`` in ``[0, 1]``; kinds the model cannot give yet are left out.
    """
    out: list[dict[Kind, np.ndarray]] = [{} for _ in scores]
    for kind in kinds:
        smoothed = [None if (r := s.raw(kind)) is None else smooth(r, window) for s in scores]
        present = [t for t in smoothed if t is not None]
        if not present:
            continue
        norm = drift_track if kind == "drift" else session_normaliser(present)
        del present  # each smoothed track is dropped once normalised
        for i, t in enumerate(smoothed):
            if t is not None:
                out[i][kind] = norm(t).astype(np.float32)  # ranks in [0, 1]: float32 is plenty, at half the memory
                smoothed[i] = None
    return out


def intervals(track: np.ndarray, threshold: float, *, log: int, kind: Kind, min_len: int = 1, gap: int = 0):
    """Stretches where ``track`` (normalised, ``(T,)``) is at or above ``threshold``.

    Args:
        track: ``(T,)`` normalised scores.
        threshold: Highlight where the score is at least this (the user's slider).
        log: Log index, carried into the intervals.
        kind: Track kind, carried into the intervals.
        min_len: Drop stretches shorter than this many samples.
        gap: Merge stretches separated by at most this many samples.

    Returns:
        ``list[Interval]`` in time order, never overlapping.
    """
    above = np.asarray(track) >= threshold
    if not above.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
    runs = [[int(a), int(b)] for a, b in zip(edges[::2], edges[1::2], strict=True)]
    merged = [runs[0]]
    for a, b in runs[1:]:
        if a - merged[-1][1] <= gap:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    return [Interval(log, a, b, float(np.max(track[a:b])), kind) for a, b in merged if b - a >= min_len]


def highlight_intervals(
    tracks: Sequence[Mapping[Kind, np.ndarray]],
    threshold: float = 0.9,
    *,
    min_len: int = 1,
    gap: int = 0,
) -> list[Interval]:
    """Intervals of every kind of every log (see :func:`intervals`), sorted by log, kind, start."""
    out = []
    for i, per_kind in enumerate(tracks):
        for kind in KINDS:
            if kind in per_kind:
                out += intervals(per_kind[kind], threshold, log=i, kind=kind, min_len=min_len, gap=gap)
    return out
