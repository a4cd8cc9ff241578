"""The tracks above the traces as arrays: labels, the model's guess, surprise, uncertainty, highlights, suggestions
and the selection, at the decimated sample times of the visible window (NumPy only: no widgets)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import labeling
from sessions import LogInfo, Segment

from ..cycle import SessionScores
from .charts import TrackInputs, per_sample_labels


def track_inputs(
    log: LogInfo,
    t: np.ndarray,
    *,
    terrains: Sequence[str],
    segments: Sequence[Segment],
    scores: SessionScores,
    threshold: float,
    suggested: Sequence[tuple[int, int]] = (),
    current: tuple[int, int] | None = None,
    selection: tuple[int, int] | None = None,
    stretches: Sequence[labeling.PredictedStretch] = (),
    review: tuple[int, int] | None = None,
) -> TrackInputs:
    """What the tracks chart draws for the visible window of ``log``.

    Args:
        log: The log on screen.
        t: ``(P,)`` decimated sample times (s) of the visible window.
        terrains: Terrain names, in the session's order (label colours follow it).
        segments: The log's label segments.
        scores: The session's scores (tracks ranked across the session, class probabilities).
        threshold: Highlight where any track's rank is at least this.
        suggested: ``[start, stop)`` samples of the queued suggestions in this log.
        current: ``[start, stop)`` of the suggestion being shown, when it lies in this log.
        selection: ``[start, stop)`` of the range being labelled.
        stretches: The model's predicted stretches of the log (``scores.classes`` indices): the model track.
        review: ``[start, stop)`` of the stretch under review.
    """
    segs = [(s.start, s.stop, terrains.index(s.terrain)) for s in segments if s.terrain in terrains]
    idx = np.clip(np.round(t * log.rate_hz).astype(np.int64), 0, max(0, log.n_samples - 1))  # (P,)
    # everything below works on the visible stretch only: a pan must not cost the whole log
    lo, hi = (int(idx.min()), int(idx.max()) + 1) if len(idx) else (0, 0)
    rel = idx - lo
    labels = per_sample_labels(hi - lo, [(x - lo, y - lo, k) for x, y, k in segs if y > lo and x < hi])[rel]
    tracks = scores.tracks.get(log.id)
    predicted = confidence = surprise = unsure = highlight = drift = None
    if tracks is not None:
        win = {k: v[lo:hi] for k, v in tracks.items()}
        surprise = bucket_max(win["surprise"], rel)
        kinds = [k for k in ("entropy", "margin") if k in win]
        if kinds:
            unsure = bucket_max(np.maximum.reduce([win[k] for k in kinds]), rel)
        high = np.zeros(hi - lo, bool)
        for k in ("surprise", *kinds, "disagreement"):
            if k in win:
                high |= win[k] >= threshold
        highlight = high[rel]
        if "drift" in win:
            drift = bucket_max(win["drift"], rel)
    if stretches:
        order = np.asarray([terrains.index(c) if c in terrains else -1 for c in scores.classes])
        starts = np.asarray([x.start for x in stretches])
        j = np.clip(np.searchsorted(starts, idx, side="right") - 1, 0, len(stretches) - 1)  # (P,)
        predicted = order[np.asarray([x.terrain for x in stretches])[j]]
        confidence = np.asarray([x.confidence for x in stretches])[j]
    in_suggestion = np.zeros(len(idx), bool)
    for a, b in suggested:
        in_suggestion |= (idx >= a) & (idx < b)
    in_current = np.zeros(len(idx), bool)
    if current is not None:
        in_current = (idx >= current[0]) & (idx < current[1])
    in_selection = np.zeros(len(idx), bool)
    if selection is not None:
        in_selection = (idx >= selection[0]) & (idx < selection[1])
    in_review = np.zeros(len(idx), bool)
    if review is not None:
        in_review = (idx >= review[0]) & (idx < review[1])
    return TrackInputs(
        t,
        labels,
        predicted,
        surprise,
        unsure,
        highlight,
        in_suggestion,
        in_current,
        in_selection,
        confidence=confidence,
        review=in_review,
        drift=drift,
    )


def bucket_max(track: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """A ``(T,)`` track at the decimated sample indices ``idx`` (``(P,)``), keeping each span's peak."""
    if len(idx) < 2:
        return track[idx].astype(np.float64)
    edges = np.append(idx, idx[-1] + 1)
    hi = np.maximum.reduceat(track, np.clip(edges[:-1], 0, len(track) - 1))
    return np.where(np.diff(edges) > 0, hi, track[idx]).astype(np.float64)
