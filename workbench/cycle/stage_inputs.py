"""What stage 2 reads in a session, derived from the logs and kept: stage-1 outputs cached per predictor version,
stage-2 features held in memory between retrains, and each log's change points (where a terrain may change).
"""

from __future__ import annotations

import os
import threading
import uuid
from collections.abc import Sequence

import numpy as np

from sessions import FileRows, LogInfo, ModelVersion, NpyWriter, Session
from training import (
    FRAME_PREDICTOR_KIND,
    FeatureMode,
    FrameOutputs,
    FramePredictor,
    LazyFeatures,
    ModelBundle,
    Piece,
    Stage1Outputs,
    TrainConfig,
    drop_pages,
    frame_surprise,
    neighbour_pairs,
    predictor_pass,
)

from .change_point_store import log_change_points
from .front_end import log_frame_files
from .score_files import kept_array

PREDICTOR_BATCH = 64  # logs per stage-1 call when filling the cache


FRAME_MARK = "frame-surprise"  # the file that completes a log's entry in a next-frame predictor's cache


def stage1_cached(session: Session, version: ModelVersion, logs: Sequence[LogInfo]) -> bool:
    """Every one of ``logs`` has its stage-1 outputs of ``version`` in the session's cache."""
    cache = session.cache_dir(f"stage1-v{version.id:04d}")
    mark = FRAME_MARK if version.config.get("kind") == FRAME_PREDICTOR_KIND else "error"
    return all((cache / f"{x.id:06d}.{mark}.npy").exists() for x in logs)


def stage1_outputs(
    session: Session, version: ModelVersion, bundle: ModelBundle, logs: Sequence[LogInfo]
) -> dict[int, Stage1Outputs] | dict[int, FrameOutputs]:
    """Stage-1 outputs of ``logs``, computed once per predictor version and cached in the session folder.

    Stage 1 is frozen, so every stage-2 retrain reuses these instead of running it again. The outputs are written
    chunk by chunk to files and handed back as rows read on demand (``FileRows``), so a 10-hour log never sits in
    memory. A next-frame predictor's are per frame (``FrameOutputs``, read per step), an LSTM's per sample.
    """
    if isinstance(bundle.predictor, FramePredictor):
        return _frame_outputs(session, version, bundle, logs)
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


def _frame_outputs(
    session: Session, version: ModelVersion, bundle: ModelBundle, logs: Sequence[LogInfo]
) -> dict[int, FrameOutputs]:
    """The next-frame predictor's surprise and hidden features of ``logs``, per frame, cached per version."""
    assert isinstance(bundle.predictor, FramePredictor) and bundle.spectral is not None  # checked on load
    cache = session.cache_dir(f"stage1-v{version.id:04d}")
    missing = [x for x in logs if not (cache / f"{x.id:06d}.{FRAME_MARK}.npy").exists()]
    if missing:
        tag = uuid.uuid4().hex[:8]  # another process may fill the same cache: each writes its own files
        frames = log_frame_files(session, bundle.normalizer, missing, bundle.spectral)
        for x, f in zip(missing, frames, strict=True):
            surprise, hidden = frame_surprise(bundle.predictor, f)  # (N,), (N, H): a 10-hour log is 46 MB of it
            drop_pages(f)  # the pass read the whole log's mapped frames: not kept resident over a fleet's logs
            # hidden features go to disk as float16 (the LSTM's cache does the same): half the disk, 1e-3 relative
            for name, array in (("frame-hidden", hidden.astype(np.float16)), (FRAME_MARK, surprise)):
                tmp = cache / f".{x.id:06d}.{name}.{tag}.npy"
                np.save(tmp, array)
                os.replace(tmp, cache / f"{x.id:06d}.{name}.npy")  # the surprise last: it marks the entry complete
    return {
        x.id: FrameOutputs(
            kept_array(cache / f"{x.id:06d}.{FRAME_MARK}.npy"),  # small ones read: a map holds a file open
            kept_array(cache / f"{x.id:06d}.frame-hidden.npy"),
            x.n_samples,
            bundle.spectral,
        )
        for x in logs
    }


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


def signal_change_points(session: Session, log: LogInfo) -> np.ndarray:
    """Change points of a log's signals, computed once per process (a log's samples never change)."""
    key = (str(session.path), log.id, log.n_samples)
    with _cache_lock:
        hit = _CHANGE_POINTS.get(key)
    if hit is None:  # computed outside the lock: seconds on a long log; two threads at once compute the same
        # read, not mapped: a map keeps every page it read resident (10 h of logs: 0.3 GiB of a training's peak)
        hit = log_change_points(session.rows(log.id)[:], None, rate_hz=log.rate_hz)
        with _cache_lock:
            _CHANGE_POINTS[key] = hit
    return hit
