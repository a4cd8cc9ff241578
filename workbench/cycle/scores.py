"""The one scoring path: per-timestep surprise, class probabilities and ensemble disagreement of logs.

The UI's highlights and suggestions, the export's predictions, ``workbench classify`` and the label-efficiency
simulation all score through :func:`score_logs`, so what the robot's export predicts and what the UI shows cannot
drift apart. Scores are ``labeling.LogScores``: the type the suggestions take.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

import labeling
from sessions import LogInfo, ModelVersion, Session, WorkbenchError
from training import (
    Classifier,
    DriftReference,
    FrameOutputs,
    LazyFeatures,
    ModelBundle,
    SpectralSteps,
    Stage1Outputs,
    StepRows,
    WindowClassifier,
    blank_probs,
    ensemble_pass,
    frame_chunks,
    load_bundle,
)

from .frame_reduce import frame_log_scores
from .front_end import input_span, spectral_features, window_features, window_sizes
from .run_votes import with_run_votes
from .stage_inputs import stage1_outputs
from .train_stages import active_bundle, model_logs

TRACK_WINDOW = 25  # samples the highlight tracks are smoothed over (labeling.suggest's default)
EMBEDDING_MODE = "hidden+surprise"  # the suggestions' embeddings: what the label-efficiency simulation used


def score_logs(
    classifiers: Sequence[Classifier | WindowClassifier],
    features: Sequence[np.ndarray | LazyFeatures | SpectralSteps],
    surprise: Sequence[np.ndarray],
    *,
    drift: DriftReference | None = None,
    batch: int = 64,
    device: str = "cpu",
) -> list[labeling.LogScores]:
    """Score logs: the stage-2 ensemble over each log's features, reduced chunk by chunk.

    The members' ``(M, L, K)`` probabilities are reduced to their mean and disagreement one chunk at a time, never
    held for a whole log (an hour of five members is 200 MB).

    Args:
        classifiers: The ``M`` ensemble members; none (an empty sequence) before a classifier exists.
        features: Per log, ``(T, F)`` stage-2 inputs (a ``LazyFeatures`` or ``SpectralSteps`` computes only the
            chunk asked for).
        surprise: Per log, ``(T,)`` stage-1 error (``Stage1Outputs.surprise``).
        drift: The bundle's drift reference: with the default family over its frames, each step's drift score is
            computed too, from the same pass as the probabilities.
        batch: Logs per LSTM call.
        device: Torch device.

    Returns:
        Per log, ``LogScores``: ``(T,)`` surprise, and with classifiers ``(T, K)`` mean probabilities, ``(T,)``
        mutual information between prediction and member (BALD) and, with two members or more, ``(T,)`` their
        agreement (``labeling.member_agreement``), and ``(T,)`` drift where it is known.
    """
    if not classifiers:
        return [labeling.LogScores(np.asarray(s)) for s in surprise]
    windows = [c for c in classifiers if isinstance(c, WindowClassifier)]
    if len(windows) == len(classifiers) and all(isinstance(f, SpectralSteps) for f in features):
        # the default family: each member once per frame, its answer repeated over the frame's steps
        steps = [f for f in features if isinstance(f, SpectralSteps)]
        for model in windows:  # where the members run, as the step pass puts them
            model.to(device)
        return [_frame_scores(windows, f, s, drift) for f, s in zip(steps, surprise, strict=True)]
    k = classifiers[0].config.n_classes
    mean = [np.empty((len(f), k), np.float32) for f in features]
    disagreement = [np.empty(len(f), np.float32) for f in features]
    pairs = len(classifiers) >= 2  # the members' agreement needs a pair
    agreement = [np.empty(len(f), np.float32) if pairs else None for f in features]

    def reduce(i: int, a: int, b: int, probs: np.ndarray) -> None:  # probs: (M, b - a, K)
        mean[i][a:b] = probs.mean(axis=0)
        disagreement[i][a:b] = labeling.mutual_information(probs)
        if pairs:
            agreement[i][a:b] = labeling.member_agreement(probs)  # type: ignore[index]

    ensemble_pass(classifiers, features, reduce, batch=batch, device=device)
    return [
        labeling.LogScores(np.asarray(s), m, d, None, g)
        for s, m, d, g in zip(surprise, mean, disagreement, agreement, strict=True)
    ]


def _frame_scores(
    classifiers: Sequence[WindowClassifier], features: SpectralSteps, surprise: np.ndarray, drift: DriftReference | None
) -> labeling.LogScores:
    """One log's scores from the members' answers once per frame (:func:`.frame_reduce.frame_log_scores`)."""
    chunks = frame_chunks(classifiers, features, drift=drift)
    return frame_log_scores(chunks, blank_probs(classifiers), features, surprise, drift=drift is not None)


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
        embeddings: Per log, the stage-1 embedding per step (:func:`stage1_embedding`), computed from the
            memory-mapped cache for the rows sliced: what typical and diverse suggestions cluster.
        window: The tracks' smoothing, in samples (the suggestions smooth theirs the same and take these).
        span: Samples one step's prediction reads (``front_end.input_span``; 0: no fixed window): a suggestion is
            never shorter.
    """

    predictor: int | None = None
    classifier: int | None = None
    classes: tuple[str, ...] = ()
    scores: dict[int, labeling.LogScores] = field(default_factory=dict)
    tracks: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    embeddings: dict[int, LazyFeatures | StepRows] = field(default_factory=dict)
    window: int = TRACK_WINDOW
    span: int = 0


def stage1_embedding(outputs: Stage1Outputs | FrameOutputs) -> LazyFeatures | StepRows:
    """A log's suggestion embedding per step, computed for the rows sliced: the next-frame predictor's hidden
    features ``(T, H)``, or the LSTM's hidden state and surprise ``(T, H + C)`` (:data:`EMBEDDING_MODE`)."""
    return outputs.embedding() if isinstance(outputs, FrameOutputs) else outputs.lazy(EMBEDDING_MODE)


def _score_session_logs(
    session: Session,
    predictor: ModelVersion,
    bundle: ModelBundle,
    classifier: ModelBundle | None,
    log_ids: Collection[int] | None,
    *,
    votes: bool = True,
    learned: Mapping | None = None,
) -> tuple[list[LogInfo], dict, list[labeling.LogScores]]:
    logs = model_logs(session, bundle.channels)
    if log_ids is not None:
        logs = [x for x in logs if x.id in set(log_ids)]
    outs = stage1_outputs(session, predictor, bundle, logs)  # memory-mapped
    if classifier is None:
        return logs, outs, score_logs((), (), [outs[x.id].surprise() for x in logs])
    inputs = classifier.stage2_family().stage2_inputs
    if inputs == "frames":  # the front end's frames, cached per log
        features = spectral_features(session, bundle, logs, classifier.spectral)
    elif inputs == "windows":  # the samples themselves, read a slice at a time
        features = window_features(session, bundle, logs, window_sizes(classifier))
    else:  # the paper family's classifier: its predictor is an LSTM (train_classifier saw to it)
        features = [outs[x.id].lazy(classifier.feature_mode) for x in logs]
    surprise = [outs[x.id].surprise() for x in logs]
    scored = score_logs(classifier.classifiers, features, surprise, drift=classifier.drift)
    if votes:  # a run's labels carried over its own frames (run_votes.py)
        estimate = (classifier.metrics.get("estimate") or {}).get("accuracy")
        scored = with_run_votes(session, logs, outs, scored, classifier.classes, estimate=estimate, learned=learned)
    return logs, outs, scored


def compute_scores(
    session: Session,
    *,
    window: int = TRACK_WINDOW,
    log_ids: Collection[int] | None = None,
    votes: bool = True,
    tracks: bool = True,
    classifier: ModelVersion | None = None,
) -> SessionScores:
    """What the UI shows: every log scored with the active predictor (and the active classifier when it was trained
    on it), with highlight tracks and suggestion embeddings.

    Args:
        session: The session.
        window: Smoothing of the tracks, in samples.
        log_ids: Only these logs (the ones on screen, refreshed first after a retrain); their tracks are then ranked
            among themselves until the whole session is scored.
        votes: A labelled run's probabilities blended with its labels' vote (``run_votes``); off only to measure
            what that is worth.
        tracks: Rank the highlight tracks (off: ``tracks`` is empty, for a caller that ranks them over more logs).
        classifier: Score with this classifier version instead of the active one (a taught version, to teach from
            what it knows in turn).
    """
    p_version = session.active_model("predictor")
    if p_version is None:
        return SessionScores()
    bundle = load_bundle(session.path / p_version.path)
    c_version = classifier or session.active_model("classifier")
    if c_version is not None and c_version.config.get("predictor") != p_version.id:
        c_version = None  # trained on another predictor's features: its probabilities would mean nothing
    c_bundle = None if c_version is None else load_bundle(session.path / c_version.path)
    learned = None if c_version is None else c_version.config.get("labels")
    logs, outs, scored = _score_session_logs(
        session, p_version, bundle, c_bundle, log_ids, votes=votes, learned=learned
    )
    ids = [x.id for x in logs]
    ranked = labeling.normalised_tracks(scored, window=window) if tracks else []
    return SessionScores(
        p_version.id,
        None if c_version is None else c_version.id,
        () if c_bundle is None else tuple(c_bundle.classes),
        dict(zip(ids, scored, strict=True)),
        dict(zip(ids, ranked, strict=True)) if tracks else {},
        # rows are computed from the cache only where a suggestion reads them: an hour of them is 1.6 GB
        {x.id: stage1_embedding(outs[x.id]) for x in logs},
        window,
        input_span(c_bundle, bundle),
    )


def score_session(
    session: Session, log_ids: Sequence[int] | None = None, *, version: ModelVersion | None = None
) -> dict[int, labeling.LogScores]:
    """What the export predicts: logs (default: all the model uses) scored with the active classifier (or
    ``version``, the taught one the export ships) and the predictor it was trained on, from cached stage-1 outputs."""
    if version is None:
        c_version, bundle = active_bundle(session)
    else:
        c_version, bundle = version, load_bundle(session.path / version.path)
    p_version = next((v for v in session.model_versions("predictor") if v.id == c_version.config["predictor"]), None)
    if p_version is None:
        raise WorkbenchError(f"{session.path}: the predictor classifier v{c_version.id} was trained on is gone")
    logs, _, scored = _score_session_logs(
        session, p_version, bundle, bundle, log_ids, learned=c_version.config.get("labels")
    )
    return {x.id: s for x, s in zip(logs, scored, strict=True)}
