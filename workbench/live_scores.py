"""What the workbench shows and suggests from the active models: per-log surprise, probabilities, disagreement,
stage-1 features for diversity, and change points for snapping. Composes ``sessions``, ``training``, ``labeling``.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field

import numpy as np

import labeling
from sessions import LogInfo, Session
from training.bundle import load_bundle
from training.inference import LazyFeatures, ensemble_pass

from .cycle import model_logs, stage1_outputs

EMBEDDING_MODE = "hidden+surprise"  # the suggestions' embeddings: what the label-efficiency simulation used


@dataclass(frozen=True)
class SessionScores:
    """Scores of every log the active models cover, keyed by log id.

    Attributes:
        predictor: Active predictor version id (``None``: nothing trained yet, every dict is empty).
        classifier: Classifier version the probabilities come from (``None``: stage 1 only).
        classes: Class names of ``probs``' last axis.
        scores: Per log, ``labeling.LogScores`` (``(T,)`` surprise; ``(T, K)`` probs and ``(T,)`` disagreement
            once a classifier exists).
        tracks: Per log, the session-normalised, smoothed tracks in ``[0, 1]`` by kind.
        embeddings: Per log, ``(T, H + C)`` stage-1 hidden state and surprise ``|x_t − x̂_t|``, computed from the
            memory-mapped feature cache for the rows sliced: for typical and diverse suggestions, what the
            label-efficiency simulation measured them with.
    """

    predictor: int | None = None
    classifier: int | None = None
    classes: tuple[str, ...] = ()
    scores: dict[int, labeling.LogScores] = field(default_factory=dict)
    tracks: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    embeddings: dict[int, LazyFeatures] = field(default_factory=dict)


def compute_scores(session: Session, *, window: int = 25, log_ids: Collection[int] | None = None) -> SessionScores:
    """Score every log with the active predictor (and the active classifier when it was trained on it).

    Args:
        session: The session.
        window: Smoothing of the tracks, in samples.
        log_ids: Only these logs (the ones on screen, refreshed first after a retrain); their tracks are then ranked
            among themselves until the whole session is scored.
    """
    p_version = session.active_model("predictor")
    if p_version is None:
        return SessionScores()
    bundle = load_bundle(session.path / p_version.path)
    logs = model_logs(session, bundle.channels)
    if log_ids is not None:
        logs = [x for x in logs if x.id in log_ids]
    outs = stage1_outputs(session, p_version, bundle, logs)  # memory-mapped
    # rows are computed from the cache only where a suggestion reads them: an hour of them is 1.6 GB
    embeddings = {x.id: outs[x.id].lazy(EMBEDDING_MODE) for x in logs}  # (T, H + C) each
    c_version = session.active_model("classifier")
    if c_version is not None and c_version.config.get("predictor") != p_version.id:
        c_version = None  # trained on another predictor's features: its probabilities would mean nothing
    classes: tuple[str, ...] = ()
    mean_probs: list[np.ndarray | None] = [None] * len(logs)
    disagreement: list[np.ndarray | None] = [None] * len(logs)
    if c_version is not None:
        c_bundle = load_bundle(session.path / c_version.path)
        classes = tuple(c_bundle.classes)
        mean_probs = [np.empty((x.n_samples, len(classes)), np.float32) for x in logs]
        disagreement = [np.empty(x.n_samples, np.float32) for x in logs]

        def reduce(i: int, a: int, b: int, probs: np.ndarray) -> None:
            # the members' (M, L, K) probabilities are reduced chunk by chunk, never held for a whole log
            mean_probs[i][a:b] = probs.mean(axis=0)
            disagreement[i][a:b] = labeling.mutual_information(probs)

        ensemble_pass(c_bundle.classifiers, [outs[x.id].lazy(c_bundle.feature_mode) for x in logs], reduce)
    scores = {
        x.id: labeling.LogScores(outs[x.id].surprise(), p, d)
        for x, p, d in zip(logs, mean_probs, disagreement, strict=True)
    }
    ids = [x.id for x in logs]
    tracks = labeling.normalised_tracks([scores[i] for i in ids], window=window)
    return SessionScores(
        p_version.id,
        None if c_version is None else c_version.id,
        classes,
        scores,
        dict(zip(ids, tracks, strict=True)),
        embeddings,
    )


# Suggestions are short: a labelled second from many places teaches stage 2 more than the same seconds in a few
# longer stretches. On the demo logs, 140 s labelled at random reached 80-81 % held-out accuracy as 1 s pieces and
# 56-71 % as 3 s pieces (docs/design-notes.md, "Suggestion length").
SUGGESTION_S = 1.0


def suggestion_lengths(rate_hz: float, *, seconds: float = SUGGESTION_S) -> tuple[int, int]:
    """``(max_len, min_len)`` in samples of suggestions ``seconds`` long: pieces of half to all of it."""
    longest = round(seconds * rate_hz)
    return longest, max(1, longest // 2)


def suggest_for_session(
    session: Session,
    scores: SessionScores,
    change_points: dict[int, np.ndarray],
    *,
    logs: list[LogInfo],
    n: int = 12,
    strategy: labeling.Strategy = "combined",
) -> list[tuple[LogInfo, labeling.Suggestion]]:
    """The session's suggestion queue: ``n`` segments of ``SUGGESTION_S / 2`` to ``SUGGESTION_S`` to label next,
    with the log each lies in."""
    logs = [x for x in logs if x.id in scores.scores]
    if not logs:
        return []
    index = {x.id: i for i, x in enumerate(logs)}
    labelled = [(index[s.log_id], s.start, s.stop) for s in session.segments() if s.log_id in index]
    terrains = [t.name for t in session.terrains()]
    classes = list(scores.classes) or terrains
    counts = np.zeros(len(classes))
    for s in session.segments():
        if s.terrain in classes:
            counts[classes.index(s.terrain)] += s.length
    max_len, min_len = suggestion_lengths(logs[0].rate_hz)
    out = labeling.suggest(
        [scores.scores[x.id] for x in logs],
        labelled=labelled,
        label_counts=counts,
        change_points=[change_points.get(x.id, np.zeros(0, np.int64)) for x in logs],
        classes=classes,
        strategy=strategy,
        n=n,
        max_len=max_len,
        min_len=min_len,
        embeddings=[scores.embeddings[x.id] for x in logs],
    )
    return [(logs[s.log], s) for s in out]
