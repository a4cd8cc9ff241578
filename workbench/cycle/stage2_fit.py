"""Stage 2 of the cycle: a family's classifier fitted on the session's labels over its frozen stage 1, saved as the
new active version. The family says what it reads (``training.Family.stage2_inputs``: the front end's frames, the
samples a window per frame, or stage 1's outputs) and how it fits; this gathers those inputs from the session, hands
them to the family's ``fit`` (or ``fine_tune`` for a quick Retrain) and never asks which family it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from functools import partial

import numpy as np

import labeling
from sessions import LogInfo, ModelVersion, Segment, Session
from training import (
    CancelFn,
    ClassifierFit,
    FeatureMode,
    ModelBundle,
    ProgressFn,
    TrainConfig,
    WindowFitConfig,
    assign_folds,
    block_and_guard,
    load_bundle,
    never,
    recorded_family,
    to_dict,
)

from ..retrain import RETRAIN
from .checks_record import names_now
from .fit_inputs import FitInputs, fit_inputs
from .fold_record import labels_record, new_labels, recorded_pieces
from .front_end import spectral_features, stretch_units, unlabelled_stretches, window_features, window_sizes
from .scores import SessionScores
from .stage_inputs import consistency_pairs, signal_change_points, stage2_features
from .train_stages import recorded_run, save_version, stage1_family

STAGE1_FEATURES: FeatureMode = "hidden+surprise"  # what a family reading stage 1's outputs takes of them
# where a family that keeps its fits' first networks keeps them: the export's taught fit starts from the session's fit
FIT_STARTS = "fit-starts"


def train_classifier(
    session: Session,
    *,
    model: str | None = None,
    config: TrainConfig | None = None,
    window: WindowFitConfig | None = None,
    feature_mode: FeatureMode = STAGE1_FEATURES,
    hidden: int = 200,
    warm_start: bool = True,
    warm_epochs: int | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    scores: SessionScores | None = None,
    teach: bool = RETRAIN.teach,
    activate: bool = True,
    recipe: dict | None = None,
) -> ModelVersion:
    """Stage 2 on the session's labels over the active predictor's cached features; a new version, the active one
    unless ``activate`` is off.

    The family says what it reads (``Family.stage2_inputs``) and how it fits; this gathers those inputs from the
    session and saves what the family's ``fit`` (or, for a quick Retrain, ``fine_tune``) returns.

    Args:
        session: The session.
        model: A family's name (``training.family_names``); ``None``: the active classifier's family.
        config: A family reading stage 1's outputs: training settings of a fresh start. Any family: its ``device``
            (a frames family's fit from scratch runs there; the quick Retrain stays on the CPU).
        window: A frames or windows family: fit settings (``RETRAIN.window`` when ``None``).
        feature_mode: A family reading stage 1's outputs: what stage 1 hands stage 2.
        hidden: LSTM width.
        warm_start: Start from the active classifier's weights when it fits (same predictor, terrains and features),
            for a family that warm-starts.
        warm_epochs: When warm-starting, train at most this many epochs (patience 1) instead of ``config``'s: the
            UI's Retrain is a short fine-tune, since the previous models already fit all but the newest labels. It
            trains on the labels added or changed since the active version and as many older ones replayed, at
            ``RETRAIN.warm_lr_scale`` of the learning rate. A family with a ``fine_tune``: any value asks for its
            quick phase (``RETRAIN.window_steps`` steps per fold model, see :func:`_fine_tune_window`).
        progress: Called after every optimiser step or fold.
        cancel: Polled after every step or fit.
        scores: The session's scores as the page shows them (the ensemble blended with each run's label votes):
            over an unlabelled stretch where they are sure of one terrain (``labeling.taught_terrains``), that
            terrain is what the session knows there. A self-training family's fit from scratch scores its held-out
            runs on it beside their labels: the version's ``unseen_runs``, what the model that ships is expected to
            score on a run it never saw. Without them, on the labels alone.
        teach: With ``scores``, the fit also takes the terrain the session knows over a stretch as its pseudo-label
            instead of its own agreement there (``RETRAIN.teach``: off for the session's own fits; the version the
            export ships is taught, ``taught_fit.shipped_version``).
        activate: A frames or windows family's fit from scratch: make the new version the active one (off: it is
            kept beside the active version, as the taught one the export ships is).
        recipe: A frames or windows family's fit from scratch: more to record in the version's config.
    """
    inputs = fit_inputs(session, stage1_family(session, model))
    if inputs.family.stage2_inputs == "stage1":
        return _train_on_stage1(
            session,
            inputs,
            config or TrainConfig(),
            feature_mode=feature_mode,
            hidden=hidden,
            warm=warm_start,
            warm_epochs=warm_epochs,
            progress=progress,
            cancel=cancel,
        )
    settings = window or RETRAIN.window
    if warm_start and warm_epochs is not None and inputs.family.fine_tune is not None:
        quick = _fine_tune_window(session, inputs, settings, progress=progress, cancel=cancel)
        if quick is not None:
            return quick
    device = (config or TrainConfig()).device
    return _train_window(
        session,
        inputs,
        settings,
        progress=progress,
        cancel=cancel,
        device=device,
        scores=scores,
        teach=teach,
        activate=activate,
        recipe=recipe,
    )


def _train_on_stage1(
    session: Session,
    inputs: FitInputs,
    config: TrainConfig,
    *,
    feature_mode: FeatureMode,
    hidden: int,
    warm: bool,
    warm_epochs: int | None,
    progress: ProgressFn | None,
    cancel: CancelFn,
) -> ModelVersion:
    """Stage 2 of a family that reads its stage 1's outputs (the paper's LSTM classifier): warm-started from the
    active classifier where the family does and it fits, with consistency pairs when ``config`` asks for them."""
    fam, p_version, bundle, logs = inputs.family, inputs.predictor, inputs.bundle, inputs.logs
    classes, used, segments, previous = inputs.classes, inputs.used, inputs.segments, inputs.previous
    features = stage2_features(session, p_version, bundle, logs, feature_mode)
    init = None
    if (
        warm
        and fam.warm_start
        and previous is not None
        and recorded_family(previous.config) == fam.name
        and previous.config.get("predictor") == p_version.id
    ):
        old = load_bundle(session.path / previous.path)
        if old.classes == classes and old.feature_mode == feature_mode:
            init = old.classifiers
    new = None
    if init is not None and warm_epochs is not None:
        config = replace(config, max_epochs=warm_epochs, patience=1, lr=config.lr * RETRAIN.warm_lr_scale)
        new = new_labels(used, previous.config.get("labels"))
    pairs = []
    if config.consistency > 0:
        fits = config.context + 2 * config.label_piece  # a log shorter holds no pair: skip its change points
        cps = [signal_change_points(session, x) if x.n_samples >= fits else np.zeros(0, np.int64) for x in logs]
        pairs = consistency_pairs([x.n_samples for x in logs], cps, config)
    with recorded_run(session, "classifier", {"config": to_dict(config), "segments": len(segments)}) as result:
        fit = fam.fit(
            features,
            segments,
            classes,
            config=config,
            hidden=hidden,
            init=init,
            new=new,
            pairs=pairs,
            progress=progress,
            cancel=cancel,
        )
        version = _save_classifier(
            session,
            bundle,
            fit,
            logs,
            used,
            segments,
            {"classes": classes, "feature_mode": feature_mode},
            {
                "model": fam.name,
                "train": to_dict(config),
                "hidden": hidden,
                "feature_mode": feature_mode,
                "predictor": p_version.id,
                "warm_start": init is not None,
                "new_labels": None if new is None else len(new),
                "consistency_pairs": len(pairs),
            },
        )
        result["version"] = version.id
    return version


def _train_window(
    session: Session,
    inputs: FitInputs,
    settings: WindowFitConfig,
    *,
    progress: ProgressFn | None,
    cancel: CancelFn,
    device: str = "cpu",
    scores: SessionScores | None = None,
    teach: bool = False,
    activate: bool = True,
    recipe: dict | None = None,
) -> ModelVersion:
    """Stage 2 of a family on the front end's frames or on the samples a window per frame (the default family's
    window network, MiniRocket), with self-training over the unlabelled stretches of every log where the family
    learns from them (its held-out runs judged, and with ``teach`` it taught, by ``scores`` where they are sure); a
    new version (the predictor's bundle with it), the active one unless ``activate`` is off; ``recipe`` adds to
    what its config records."""
    fam, p_version, bundle, logs = inputs.family, inputs.predictor, inputs.bundle, inputs.logs
    classes, used, segments = inputs.classes, inputs.used, inputs.segments
    front = inputs.front_end(session)
    if fam.stage2_inputs == "windows":  # the samples themselves, a window per hop of the front end
        features = window_features(session, bundle, logs, window_sizes(bundle, front))
    else:
        features = spectral_features(session, bundle, logs, front)
    stretches, spans = [], {}
    if settings.self_training and fam.self_training:
        points = partial(signal_change_points, session)
        stretches = unlabelled_stretches(logs, used, points, shortest=front.span)
        if settings.unit_agree:  # the pieces of a span judged together (off by default: WindowFitConfig)
            spans = {"units": stretch_units(stretches, lambda i: points(logs[i]))}
        if scores is not None:
            spans["known"] = taught_classes(session, scores, logs, classes, stretches)
            if teach:
                spans["taught"] = spans["known"]
    params = {"model": fam.name, "window": to_dict(settings), "segments": len(segments)}
    with recorded_run(session, "classifier", params) as result:
        fit = fam.fit(
            features,
            segments,
            classes,
            config=settings,
            stretches=stretches,
            progress=progress,
            cancel=cancel,
            **spans,
            **({} if device == "cpu" else {"device": device}),  # a family without a CUDA path is refused before
            **({"starts": session.cache_dir(FIT_STARTS)} if fam.keeps_starts else {}),
        )
        if unseen := fit.metrics.get("unseen_runs"):  # the fit's runs are the logs' indices: named as the page does
            unseen["per_run"] = {logs[int(k)].name: v for k, v in unseen["per_run"].items()}
        version = _save_classifier(
            session,
            bundle,
            fit,
            logs,
            used,
            segments,
            {"classes": classes, "feature_mode": "spectral", "spectral": front},
            {
                "model": fam.name,
                "window": to_dict(settings),
                "feature_mode": "spectral",
                "predictor": p_version.id,
                "warm_start": False,
                "self_training_stretches": len(stretches),
                "known_stretches": int((np.asarray(spans["known"]) >= 0).sum()) if "known" in spans else 0,
                "taught": "taught" in spans,
                **(recipe or {}),
            },
            activate=activate,
        )
        result["version"] = version.id
    return version


def _fine_tune_window(
    session: Session, inputs: FitInputs, settings: WindowFitConfig, *, progress: ProgressFn | None, cancel: CancelFn
) -> ModelVersion | None:
    """A frames family's quick phase (the default family's): the active fold models fine-tuned on the labels added
    or changed since; a new, active version. ``None`` (fit from scratch) unless the active classifier is an ensemble
    of this family of two or more fold models over the same predictor and terrains that recorded its segments'
    folds."""
    fam, p_version, bundle, previous = inputs.family, inputs.predictor, inputs.bundle, inputs.previous
    if previous is None or previous.config.get("model") != fam.name or fam.fine_tune is None:
        return None
    seen = previous.config.get("labels") or {}
    if previous.config.get("predictor") != p_version.id or not seen.get("ids"):
        return None
    old = load_bundle(session.path / previous.path)
    logs, classes, used, segments = inputs.logs, inputs.classes, inputs.used, inputs.segments
    if old.classes != classes or old.spectral is None or len(old.classifiers) < 2:
        return None
    fresh = set(new_labels(used, seen) or [])
    recorded = recorded_pieces(used, segments, seen, fresh, block_and_guard(old.spectral)[0])
    if recorded is None:  # a record that does not add up: trust none of it
        return None
    pieces, known = recorded
    folds = assign_folds([segments[i][3] for i, _, _ in pieces], known, len(old.classifiers))
    new = [j for j, (i, _, _) in enumerate(pieces) if i in fresh]
    # only labelled logs' frames are read: a fine-tune never looks at the rest (thousands of trials at QCAT scale)
    needed = sorted({s[0] for s in segments})
    at = {i: j for j, i in enumerate(needed)}
    features = spectral_features(session, bundle, [logs[i] for i in needed], old.spectral)
    params = {"model": fam.name, "quick": True, "steps": RETRAIN.window_steps, "segments": len(segments)}
    with recorded_run(session, "classifier", params) as result:
        fit = fam.fine_tune(
            features,
            [(at[segments[i][0]], a, b, segments[i][3]) for i, a, b in pieces],
            classes,
            old.classifiers,
            folds=folds,
            new=new,
            steps=RETRAIN.window_steps,
            lr_scale=RETRAIN.window_lr_scale,
            config=settings,
            progress=progress,
            cancel=cancel,
        )
        fit.pieces = pieces
        version = _save_classifier(
            session,
            bundle,
            fit,
            logs,
            used,
            segments,
            {"classes": classes, "feature_mode": "spectral", "spectral": old.spectral},
            {
                "model": fam.name,
                "window": to_dict(settings),
                "feature_mode": "spectral",
                "predictor": p_version.id,
                "warm_start": True,
                "fine_tuned_from": previous.id,
                "steps": RETRAIN.window_steps,
                "lr_scale": RETRAIN.window_lr_scale,
                "new_labels": len(new),
            },
        )
        result["version"] = version.id
    return version


def _save_classifier(
    session: Session,
    bundle: ModelBundle,
    fit: ClassifierFit,
    logs: Sequence[LogInfo],
    used: Sequence[Segment],
    segments: Sequence[tuple[int, int, int, int]],
    stage2: dict,
    recipe: dict,
    *,
    activate: bool = True,
) -> ModelVersion:
    """Save a fitted stage 2 with its predictor as a new classifier version, the active one unless ``activate``.

    Args:
        stage2: The bundle's stage-2 fields beside the models (classes, features, front end).
        recipe: The version's config: how it was trained; the labels it saw are added.
        activate: Make it the active version (off: a version kept beside the active one, as the taught one is).
    """
    labelled = sum(s[2] - s[1] for s in segments)
    total = sum(x.n_samples for x in logs)
    metrics = {**fit.metrics, "labelled_fraction": labelled / total, "labelled_seconds": labelled / logs[0].rate_hz}
    full = replace(
        bundle,
        classifiers=fit.models,
        drift=fit.drift,
        metrics=metrics,
        info={**bundle.info, "predictor_version": recipe["predictor"], "history": fit.history},
        **stage2,
    )
    record = {**recipe, "labels": labels_record(fit, used, segments)}
    return save_version(session, "classifier", full, record, activate=activate)


def taught_classes(
    session: Session,
    scores: SessionScores,
    logs: Sequence[LogInfo],
    classes: Sequence[str],
    stretches: Sequence[tuple[int, int, int]],
) -> np.ndarray:
    """Per stretch, the class (an index into ``classes``) the session's scores are sure of there, ``-1`` elsewhere:
    the scores' classes taken by what the session calls those terrains now, a class the fit lacks never taught."""
    names = names_now(session, scores)
    columns = [names.index(c) if c in names else -1 for c in classes]

    def blended(log: LogInfo) -> np.ndarray | None:
        s = scores.scores.get(log.id)
        return None if s is None or s.probs is None or len(s.probs) != log.n_samples else s.probs  # (T, K_teacher)

    return labeling.taught_terrains([blended(x) for x in logs], stretches, columns=columns)
