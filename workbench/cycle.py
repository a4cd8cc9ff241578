"""The human-in-the-loop cycle without a UI: train stage 1 on all logs, cache its outputs, train stage 2 on the
labels, score every log. Composes ``sessions`` (data, labels, versions) and ``training`` (models, arrays only).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import threading
import uuid
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

import labeling
from sessions import FileRows, LogInfo, ModelVersion, NpyWriter, Segment, Session, WorkbenchError
from training import (
    CancelFn,
    Cancelled,
    FeatureMode,
    LazyFeatures,
    ModelBundle,
    Piece,
    ProgressFn,
    Stage1Outputs,
    TrainConfig,
    distributed,
    fit_classifier,
    fit_predictor,
    load_bundle,
    neighbour_pairs,
    never,
    predictor_pass,
    save_bundle,
    to_dict,
)

from .retrain import RETRAIN


def model_logs(session: Session, channels: Sequence[str] | None = None) -> list[LogInfo]:
    """The logs a model uses: those with ``channels``, or with the most common channel set of the session."""
    logs = session.logs()
    if not logs:
        raise WorkbenchError(f"{session.path}: no logs yet; ingest some first")
    if channels is None:
        channels = Counter(log.channel_names for log in logs).most_common(1)[0][0]
    return [log for log in logs if log.channel_names == tuple(channels)]


def _save_version(session: Session, stage: str, bundle: ModelBundle, extra: dict) -> ModelVersion:
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
def _recorded_run(session: Session, kind: str, params: dict) -> Iterator[dict]:
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
    checkpoint_every: int = 100,
) -> ModelVersion:
    """Stage 1 on every log of the session's main channel set; saved as a new, active predictor version.

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
    with _recorded_run(session, "predictor", params) as result:
        fit = fit_predictor(
            rows,
            config=config,
            hidden=hidden,
            progress=progress,
            cancel=cancel,
            checkpoint=checkpoint,
            checkpoint_every=checkpoint_every,
            on_resume=on_resume,
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
        version = _save_version(
            session, "predictor", bundle, {"train": to_dict(config), "hidden": hidden, "logs": [x.id for x in logs]}
        )
        result["version"] = version.id
    with contextlib.suppress(OSError):
        checkpoint.unlink()  # the version holds the result now
    distributed.broadcast_json({"version": version.id})
    return version


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


PREDICTOR_BATCH = 64  # logs per stage-1 call when filling the cache


def stage1_outputs(
    session: Session, version: ModelVersion, bundle: ModelBundle, logs: Sequence[LogInfo]
) -> dict[int, Stage1Outputs]:
    """Stage-1 outputs of ``logs``, computed once per predictor version and cached in the session folder.

    Stage 1 is frozen, so every stage-2 retrain reuses these instead of running it again. The outputs are written
    chunk by chunk to files and handed back as rows read on demand (``FileRows``), so a 10-hour log never sits in
    memory.
    """
    cache = session.cache_dir(f"stage1-v{version.id:04d}")
    missing = [x for x in logs if not (cache / f"{x.id:06d}.error.npy").exists()]
    if missing:
        h, c = bundle.predictor.config.hidden, bundle.predictor.config.n_channels
        tag = uuid.uuid4().hex[:8]  # another process may fill the same cache: each writes its own files

        def part(log: LogInfo, name: str, width: int, dtype: type) -> NpyWriter:
            return NpyWriter(cache / f".{log.id:06d}.{name}.{tag}.npy", (log.n_samples, width), dtype)

        # rows go to disk as they are computed and are read a chunk at a time: a long log never sits in memory;
        # a group of logs at a time, each log's files open only while its group runs
        missing.sort(key=lambda x: -x.n_samples)
        for g0 in range(0, len(missing), PREDICTOR_BATCH):
            group = missing[g0 : g0 + PREDICTOR_BATCH]
            sinks: list[Stage1Outputs] = []
            try:
                # hidden states lie in (-1, 1): float16 keeps them to 5e-4 at half the disk
                for x in group:
                    sinks.append(
                        Stage1Outputs(
                            part(x, "hidden", h, np.float16),
                            part(x, "error", c, np.float32),
                            part(x, "estimate", c, np.float32),
                        )
                    )
                predictor_pass(
                    bundle.predictor,
                    bundle.normalizer,
                    [session.rows(x.id) for x in group],
                    sinks,
                    batch=PREDICTOR_BATCH,
                )
                for log, sink in zip(group, sinks, strict=True):
                    for name in ("hidden", "estimate", "error"):  # error last: its file marks the entry complete
                        writer = getattr(sink, name)
                        writer.close(sync=False)  # a cache: recomputed if lost, as np.save never synced it either
                        os.replace(writer.path, cache / f"{log.id:06d}.{name}.npy")
            finally:
                for sink in sinks:
                    for writer in (sink.hidden, sink.error, sink.estimate):
                        writer.abort()  # a no-op for the files already in place
    result = {}
    for x in logs:
        base = cache / f"{x.id:06d}"
        result[x.id] = Stage1Outputs(
            FileRows.open_npy(f"{base}.hidden.npy"),
            FileRows.open_npy(f"{base}.error.npy"),
            FileRows.open_npy(f"{base}.estimate.npy"),
        )
    return result


FEATURE_CACHE_BYTES = 2 << 30  # stage-2 inputs kept in memory between retrains when they fit (QCAT scale: 1 GB)
# The UI's threads (a Retrain's job, the scoring worker, viser's callbacks) share these caches: one lock guards both.
_cache_lock = threading.Lock()
_features: dict[tuple, list[np.ndarray]] = {}


def stage2_features(
    session: Session, version: ModelVersion, bundle: ModelBundle, logs: Sequence[LogInfo], mode: FeatureMode
) -> list[np.ndarray] | list[LazyFeatures]:
    """Stage 2's ``(T, F)`` inputs of ``logs``, kept in memory for the next retrain when they fit the budget.

    A Retrain in the UI reads the same frozen features every time; loading thousands of cached files and building
    the inputs took 7 s of a 40 s retrain at QCAT scale. One entry is kept (the latest session, predictor, logs).
    Features past the budget stay on disk: lazy features computed from the memory-mapped cache, batch by batch.
    """
    key = (str(session.path), version.id, mode, tuple(x.id for x in logs))
    with _cache_lock:
        hit = _features.get(key)
    if hit is not None:
        return hit
    outs = stage1_outputs(session, version, bundle, logs)
    lazy = [outs[x.id].lazy(mode) for x in logs]
    if sum(f.shape[0] * f.shape[1] * 4 for f in lazy) > FEATURE_CACHE_BYTES:
        return lazy  # too big to hold: each batch computes its rows from the memory-mapped cache
    features = [outs[x.id].features(mode) for x in logs]
    for f in features:
        f.setflags(write=False)  # shared between retrains: nobody may change them
    with _cache_lock:
        _features.clear()
        _features[key] = features
    return features


def log_change_points(samples: np.ndarray, surprise: np.ndarray | None, *, rate_hz: float) -> np.ndarray:
    """Change points (sample indices) of one log over its z-scored channels and, when known, its surprise."""
    x = np.asarray(samples, np.float32)
    z = (x - x.mean(axis=0)) / (x.std(axis=0) + 1e-6)  # (T, C)
    if surprise is not None:
        z = np.column_stack([z, surprise])
    return labeling.change_points(z, block=max(1, round(0.25 * rate_hz)))


def consistency_pairs(
    lengths: Sequence[int], change_points: Sequence[np.ndarray], config: TrainConfig
) -> list[tuple[Piece, Piece]]:
    """Stage 2's unlabelled neighbour pairs over logs of ``lengths`` samples: windows as long as a training piece
    (context and labelled stretch), one labelled stretch apart, no change point between their last steps; a pair
    starts every quarter stretch."""
    window = config.context + config.label_piece
    return neighbour_pairs(
        lengths, window=window, gap=config.label_piece, stride=max(1, config.label_piece // 4), boundaries=change_points
    )


_CHANGE_POINTS: dict[tuple[str, int, int], np.ndarray] = {}  # (session, log, samples): a log's signals never change


def _signal_change_points(session: Session, log: LogInfo) -> np.ndarray:
    key = (str(session.path), log.id, log.n_samples)
    with _cache_lock:
        hit = _CHANGE_POINTS.get(key)
    if hit is None:  # computed outside the lock: seconds on a long log; two threads at once compute the same
        hit = log_change_points(session.array(log.id), None, rate_hz=log.rate_hz)
        with _cache_lock:
            _CHANGE_POINTS[key] = hit
    return hit


def train_classifier(
    session: Session,
    *,
    config: TrainConfig | None = None,
    feature_mode: FeatureMode = "hidden+surprise",
    hidden: int = 200,
    warm_start: bool = True,
    warm_epochs: int | None = None,
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ModelVersion:
    """Stage 2 on the session's labels over the active predictor's cached features; a new, active version.

    Args:
        session: The session.
        config: Training settings of a fresh start.
        feature_mode: What stage 1 hands stage 2.
        hidden: LSTM width.
        warm_start: Start from the active classifier's weights when it fits (same predictor, terrains and features).
        warm_epochs: When warm-starting, train at most this many epochs (patience 1) instead of ``config``'s: the
            UI's Retrain is a short fine-tune, since the previous models already fit all but the newest labels. It
            trains on the labels added or changed since the active version and as many older ones replayed, at
            ``RETRAIN.warm_lr_scale`` of the learning rate.
        progress: Called after every optimiser step.
        cancel: Polled after every step.
    """
    config = config or TrainConfig()
    p_version, bundle = active_predictor(session)
    logs = model_logs(session, bundle.channels)
    index = {x.id: i for i, x in enumerate(logs)}
    classes = tuple(t.name for t in session.terrains())
    used = [s for s in session.segments() if s.log_id in index]
    segments = [(index[s.log_id], s.start, s.stop, classes.index(s.terrain)) for s in used]
    if len({s[3] for s in segments}) < 2:
        raise WorkbenchError(f"{session.path}: label segments of at least two terrains before training the classifier")
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
        new = _new_labels(used, previous.config.get("labels"))
    pairs = []
    if config.consistency > 0:
        fits = config.context + 2 * config.label_piece  # a log shorter holds no pair: skip its change points
        cps = [_signal_change_points(session, x) if x.n_samples >= fits else np.zeros(0, np.int64) for x in logs]
        pairs = consistency_pairs([x.n_samples for x in logs], cps, config)
    with _recorded_run(session, "classifier", {"config": to_dict(config), "segments": len(segments)}) as result:
        fit = fit_classifier(
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
        labelled = sum(s[2] - s[1] for s in segments)
        total = sum(x.n_samples for x in logs)
        metrics = {**fit.metrics, "labelled_fraction": labelled / total, "labelled_seconds": labelled / logs[0].rate_hz}
        full = replace(
            bundle,
            classifiers=fit.models,
            classes=classes,
            feature_mode=feature_mode,
            metrics=metrics,
            info={**bundle.info, "predictor_version": p_version.id, "history": fit.history},
        )
        version = _save_version(
            session,
            "classifier",
            full,
            {
                "train": to_dict(config),
                "hidden": hidden,
                "feature_mode": feature_mode,
                "predictor": p_version.id,
                "warm_start": init is not None,
                "new_labels": None if new is None else len(new),
                "consistency_pairs": len(pairs),
                "labels": {"ids": [s.id for s in used], "as_of": max((s.updated_at for s in used), default="")},
            },
        )
        result["version"] = version.id
    return version


def _new_labels(used: Sequence[Segment], seen: dict | None) -> list[int] | None:
    """Indices into ``used`` of segments a version trained on ``seen`` (its recorded ids and newest change) did not
    see: added or changed since. ``None`` (train on all) when the version recorded nothing."""
    if not seen:
        return None
    ids, as_of = set(seen.get("ids", ())), seen.get("as_of", "")
    return [i for i, s in enumerate(used) if s.id not in ids or s.updated_at > as_of]


def active_bundle(session: Session) -> tuple[ModelVersion, ModelBundle]:
    """The active classifier version and its full bundle (both stages)."""
    version = session.active_model("classifier")
    if version is None:
        raise WorkbenchError(f"{session.path}: no classifier yet; label some segments and run `workbench train`")
    return version, load_bundle(session.path / version.path)
