"""The human-in-the-loop cycle without a UI: train stage 1 on all logs, cache its outputs, train stage 2 on the
labels, score every log. Composes ``sessions`` (data, labels, versions) and ``training`` (models, arrays only).
"""

from __future__ import annotations

import contextlib
import shutil
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from sessions import FileRows, LogInfo, ModelVersion, Segment, Session, WorkbenchError
from training import (
    CancelFn,
    Cancelled,
    ClassifierFit,
    Family,
    FeatureMode,
    ModelBundle,
    ProgressFn,
    SpectralConfig,
    TrainConfig,
    WindowFitConfig,
    assign_folds,
    block_and_guard,
    distributed,
    family,
    family_names,
    fit_classifier,
    fit_predictor,
    load_bundle,
    never,
    save_bundle,
    to_dict,
)

from ..retrain import RETRAIN
from .fold_record import labels_record, new_labels, recorded_pieces
from .front_end import (
    choose_front_end,
    spectral_features,
    stretch_units,
    unlabelled_stretches,
    window_features,
    window_sizes,
)
from .stage_inputs import consistency_pairs, signal_change_points, stage2_features

MODEL_FAMILIES = family_names()  # `--model`: the registry's names (training.registry), the default first
PAPER_FEATURES: FeatureMode = "hidden+surprise"  # what the paper family's stage 2 reads of stage 1


def model_logs(session: Session, channels: Sequence[str] | None = None) -> list[LogInfo]:
    """The logs a model uses: those with ``channels``, or with the most common channel set of the session."""
    logs = session.logs()
    if not logs:
        raise WorkbenchError(f"{session.path}: no logs yet; ingest some first")
    if channels is None:
        channels = Counter(log.channel_names for log in logs).most_common(1)[0][0]
    return [log for log in logs if log.channel_names == tuple(channels)]


def save_version(session: Session, stage: str, bundle: ModelBundle, extra: dict) -> ModelVersion:
    path = session.next_model_dir()
    if path.exists():  # a crashed save that got as far as the rename but not the catalog
        shutil.rmtree(path)
    try:
        save_bundle(bundle, path)  # whole or not at all: written under a temporary name
    except OSError as exc:
        raise WorkbenchError(
            f"{session.path}: cannot save the {stage} model ({exc.strerror or exc}); the active models are unchanged"
        ) from None
    try:
        return session.register_model(stage, path, config=extra, metrics=bundle.metrics)
    except BaseException:
        shutil.rmtree(path, ignore_errors=True)
        raise


@contextlib.contextmanager
def recorded_run(session: Session, kind: str, params: dict) -> Iterator[dict]:
    """Record a training run in the session: "done" with the result the block fills in, else why it ended."""
    run = session.start_run(kind, params)
    result: dict = {}
    try:
        yield result
    except BaseException as exc:
        session.finish_run(run, "cancelled" if isinstance(exc, Cancelled) else "failed", {"error": str(exc)})
        raise
    session.finish_run(run, "done", result)


PREDICTOR_CHECKPOINT = "predictor.safetensors"  # in the session's cache/checkpoints/


def train_predictor(
    session: Session,
    *,
    config: TrainConfig | None = None,
    hidden: int = 200,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
    on_resume: Callable[[int, int], None] | None = None,
    on_other: Callable[[str], None] | None = None,
    checkpoint_every: int = 100,
) -> ModelVersion:
    """The paper family's stage 1 (its LSTM predictor of the next sample) on every log of the session's main channel
    set; saved as a new, active predictor version. :func:`train_stage1` picks a family's stage 1.

    Resumable: training keeps a checkpoint in the session (every ``checkpoint_every`` batches and every epoch), and
    a run with the same settings on the same logs goes on from it (``on_resume`` hears where). Under ``torchrun``
    this runs in the main process, the only one that opens the session; the others run
    :func:`follow_predictor_training` and train on their share of each batch.
    """
    config = config or TrainConfig()
    world = distributed.current()
    logs = model_logs(session)
    checkpoint = session.cache_dir("checkpoints") / PREDICTOR_CHECKPOINT
    rows = [session.rows(x.id) for x in logs]  # read a batch at a time, never whole
    # the other processes never open the database (SQLite's WAL needs one machine): they are told the files
    distributed.broadcast_json({"files": [str(session.path / x.file) for x in logs], "checkpoint": str(checkpoint)})
    params = {"config": to_dict(config), "hidden": hidden, "logs": [x.id for x in logs], "processes": world.size}
    with recorded_run(session, "predictor", params) as result:
        fit = fit_predictor(
            rows,
            config=config,
            hidden=hidden,
            progress=progress,
            cancel=cancel,
            checkpoint=checkpoint,
            checkpoint_every=checkpoint_every,
            on_resume=on_resume,
            on_other=on_other,
        )
        info = {
            "logs": len(logs),
            "timesteps": int(sum(x.n_samples for x in logs)),
            "history": fit.history,
            "processes": world.size,
            "resumed_from": fit.resumed_from,
        }
        bundle = ModelBundle(
            fit.model,
            fit.normalizer,
            logs[0].channel_names,
            logs[0].rate_hz,
            metrics={
                "val_mse": min(h["val_loss"] for h in fit.history),
                "best_epoch": fit.best_epoch,
                "epochs": len(fit.history),
            },
            info=info,
        )
        version = save_version(
            session, "predictor", bundle, {"train": to_dict(config), "hidden": hidden, "logs": [x.id for x in logs]}
        )
        result["version"] = version.id
    if fit.checkpoint is not None:
        with contextlib.suppress(OSError):
            fit.checkpoint.unlink()  # the version holds the result now
    distributed.broadcast_json({"version": version.id})
    return version


def stage1_family(session: Session, model: str | None) -> Family:
    """The family ``model`` names, or the active classifier's (``"default"`` before any)."""
    try:
        return family(model or classifier_family(session))
    except KeyError as exc:
        raise WorkbenchError(str(exc.args[0])) from None


def front_end_of(session: Session, bundle: ModelBundle, logs: Sequence[LogInfo]) -> SpectralConfig:
    """The default family's front end: the next-frame predictor's (its frames are what it learned), else chosen
    from the logs (a session whose stage 1 is the LSTM)."""
    return bundle.spectral if bundle.spectral is not None else choose_front_end(session, logs)


def require_lstm(session: Session, version: ModelVersion, bundle: ModelBundle) -> None:
    """Refuse the paper family's stage 2 over a next-frame predictor, in one line with what to run."""
    if bundle.stage1_kind != "lstm":
        raise WorkbenchError(
            f"{session.path}: the paper family reads the LSTM predictor's outputs, and the active predictor "
            f"v{version.id} is the default family's (next spectral frame); run `workbench train {session.path} "
            "--model paper` to train both stages of the paper family (labels are kept)"
        )


def follow_predictor_training(
    *, config: TrainConfig | None = None, hidden: int = 200, checkpoint_every: int = 100, cancel: CancelFn = never
) -> int:
    """What every ``torchrun`` process but the main one runs beside :func:`train_predictor`: it trains on its share
    of the logs the main process names, reading their files only, and returns the id of the version the main
    process saved. It never opens the session's database: on several machines that is a shared file system, where
    SQLite's write-ahead log would not be safe."""
    told = distributed.broadcast_json()
    assert isinstance(told, dict)
    rows = [FileRows.open_npy(f) for f in told["files"]]
    fit_predictor(
        rows,
        config=config or TrainConfig(),
        hidden=hidden,
        cancel=cancel,
        checkpoint=Path(told["checkpoint"]),
        checkpoint_every=checkpoint_every,
    )
    done = distributed.broadcast_json()
    assert isinstance(done, dict)
    return int(done["version"])


def active_predictor(session: Session) -> tuple[ModelVersion, ModelBundle]:
    version = session.active_model("predictor")
    if version is None:
        raise WorkbenchError(
            f"{session.path}: no predictor yet; run `workbench train {session.path} --stage predictor`"
        )
    return version, load_bundle(session.path / version.path)


def classifier_family(session: Session) -> str:
    """The family of the active classifier (what a Retrain trains again), ``"default"`` before any."""
    active = session.active_model("classifier")
    return "default" if active is None else str(active.config.get("model", "paper"))


def _labelled(session: Session, logs: Sequence[LogInfo]) -> tuple[tuple[str, ...], list[Segment], list]:
    index = {x.id: i for i, x in enumerate(logs)}
    used = [s for s in session.segments() if s.log_id in index]
    # the classes are the terrains labelled: a terrain nobody labelled would be an empty row of the confusion matrix
    # and a column of zeros in every prediction file
    labelled = {s.terrain for s in used}
    classes = tuple(t.name for t in session.terrains() if t.name in labelled)
    segments = [(index[s.log_id], s.start, s.stop, classes.index(s.terrain)) for s in used]
    if len({s[3] for s in segments}) < 2:
        raise WorkbenchError(f"{session.path}: label segments of at least two terrains before training the classifier")
    return classes, used, segments


def train_classifier(
    session: Session,
    *,
    model: str | None = None,
    config: TrainConfig | None = None,
    window: WindowFitConfig | None = None,
    feature_mode: FeatureMode = PAPER_FEATURES,
    hidden: int = 200,
    warm_start: bool = True,
    warm_epochs: int | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ModelVersion:
    """Stage 2 on the session's labels over the active predictor's cached features; a new, active version.

    Args:
        session: The session.
        model: ``"default"`` (the window classifier on spectral summaries, fitted with self-training) or
            ``"paper"`` (the paper's LSTM on stage-1 features); ``None``: the active classifier's family.
        config: Paper family: training settings of a fresh start.
        window: Default family: fit settings (``RETRAIN.window`` when ``None``).
        feature_mode: Paper family: what stage 1 hands stage 2.
        hidden: LSTM width.
        warm_start: Start from the active classifier's weights when it fits (same predictor, terrains and features).
        warm_epochs: When warm-starting, train at most this many epochs (patience 1) instead of ``config``'s: the
            UI's Retrain is a short fine-tune, since the previous models already fit all but the newest labels. It
            trains on the labels added or changed since the active version and as many older ones replayed, at
            ``RETRAIN.warm_lr_scale`` of the learning rate. Default family: any value asks for its quick phase
            (``RETRAIN.window_steps`` steps per fold model, see :func:`_fine_tune_window`).
        progress: Called after every optimiser step (paper) or fold (default).
        cancel: Polled after every step (paper) or fit (default).
    """
    fam = stage1_family(session, model)
    if fam.stage2_inputs in ("frames", "windows"):
        settings = window or RETRAIN.window
        if warm_start and warm_epochs is not None and fam.fine_tune is not None:
            quick = _fine_tune_window(session, fam, settings, progress=progress, cancel=cancel)
            if quick is not None:
                return quick
        return _train_window(session, fam, settings, progress=progress, cancel=cancel)
    config = config or TrainConfig()
    p_version, bundle = active_predictor(session)
    require_lstm(session, p_version, bundle)
    logs = model_logs(session, bundle.channels)
    classes, used, segments = _labelled(session, logs)
    features = stage2_features(session, p_version, bundle, logs, feature_mode)
    init = None
    previous = session.active_model("classifier")
    if warm_start and previous is not None and previous.config.get("predictor") == p_version.id:
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
        fit = fit_classifier(  # the paper family's fit: its warm start, replayed labels and consistency pairs
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
    session: Session, fam: Family, settings: WindowFitConfig, *, progress: ProgressFn | None, cancel: CancelFn
) -> ModelVersion:
    """Stage 2 of a family on the front end's frames (the default family's window network), with self-training
    over the unlabelled stretches of every log; a new, active version (the predictor's bundle with it)."""
    p_version, bundle = active_predictor(session)
    logs = model_logs(session, bundle.channels)
    classes, used, segments = _labelled(session, logs)
    front = front_end_of(session, bundle, logs)
    if fam.stage2_inputs == "windows":  # the samples themselves, a window per hop of the front end
        features = window_features(session, bundle, logs, window_sizes(bundle, front))
    else:
        features = spectral_features(session, bundle, logs, front)
    stretches, spans = [], {}
    if settings.self_training and fam.stage2_inputs == "frames":
        points = partial(signal_change_points, session)
        stretches = unlabelled_stretches(logs, used, points, shortest=front.span)
        if settings.unit_agree:  # the pieces of a span judged together (off by default: WindowFitConfig)
            spans = {"units": stretch_units(stretches, lambda i: points(logs[i]))}
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
        )
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
            },
        )
        result["version"] = version.id
    return version


def _fine_tune_window(
    session: Session, fam: Family, settings: WindowFitConfig, *, progress: ProgressFn | None, cancel: CancelFn
) -> ModelVersion | None:
    """A frames family's quick phase (the default family's): the active fold models fine-tuned on the labels added
    or changed since; a new, active version. ``None`` (fit from scratch) unless the active classifier is an ensemble
    of this family of two or more fold models over the same predictor and terrains that recorded its segments'
    folds."""
    previous = session.active_model("classifier")
    if previous is None or previous.config.get("model") != fam.name or fam.fine_tune is None:
        return None
    p_version, bundle = active_predictor(session)
    seen = previous.config.get("labels") or {}
    if previous.config.get("predictor") != p_version.id or not seen.get("ids"):
        return None
    old = load_bundle(session.path / previous.path)
    logs = model_logs(session, bundle.channels)
    classes, used, segments = _labelled(session, logs)
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
) -> ModelVersion:
    """Save a fitted stage 2 with its predictor as a new, active classifier version.

    Args:
        stage2: The bundle's stage-2 fields beside the models (classes, features, front end).
        recipe: The version's config: how it was trained; the labels it saw are added.
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
    return save_version(session, "classifier", full, {**recipe, "labels": labels_record(fit, used, segments)})


def active_bundle(session: Session) -> tuple[ModelVersion, ModelBundle]:
    """The active classifier version and its full bundle (both stages)."""
    version = session.active_model("classifier")
    if version is None:
        raise WorkbenchError(f"{session.path}: no classifier yet; label some segments and run `workbench train`")
    return version, load_bundle(session.path / version.path)
