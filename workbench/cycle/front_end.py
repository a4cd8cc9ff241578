"""The default family's inputs in a session: the spectral front end's frames of every log, computed once
per input normalisation and front end and cached in the session folder, and the unlabelled stretches self-training
reads.
"""

from __future__ import annotations

import hashlib
import json
import os
import uuid
from collections.abc import Callable, Sequence

import numpy as np

import labeling
from sessions import LogInfo, Segment, Session
from training import ModelBundle, Normalizer, RawSteps, SpectralConfig, SpectralSteps, log_frames

SAMPLE_S = 600.0  # seconds of each of the first logs read to tell fast channels from slow ones
STRETCH_S = 5.0  # longest unlabelled stretch self-training judges as one (BorealTC's partition, where it was measured)
WINDOW_S = 1.7  # a "windows" family's input (MiniRocket's): BorealTC's window, the default family's span


def choose_front_end(session: Session, logs: Sequence[LogInfo]) -> SpectralConfig:
    """The front end of a session's logs: sizes from their rate, fast and slow channels from a sample of them."""
    rate = logs[0].rate_hz
    take = int(SAMPLE_S * rate)
    sample = np.concatenate([np.asarray(session.rows(x.id)[:take], np.float32) for x in logs[:5]])
    return SpectralConfig.for_log(sample, rate)


def _digest(normalizer: Normalizer, config: SpectralConfig) -> str:
    text = json.dumps({"normalizer": normalizer.to_dict(), "front": config.to_dict()}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def log_frame_files(
    session: Session,
    normalizer: Normalizer,
    logs: Sequence[LogInfo],
    config: SpectralConfig,
    *,
    progress: Callable[[int, int], None] | None = None,
    cancel: Callable[[], bool] = lambda: False,
) -> list[np.ndarray]:
    """Per log, its ``(N, F)`` frames, memory-mapped from the session's cache (computed once and kept).

    The cache is keyed by what the frames depend on, the input normalisation and the front end, not by a model
    version: the next-frame predictor trains on them before its version exists, and every classifier over the same
    predictor reads them again. Each log's file appears whole or not at all, so a stopped run goes on from the logs
    already done.

    Args:
        progress: Called after each log computed with ``(done, to do)``.
        cancel: Polled between logs; when it returns True, ``Cancelled`` is raised.
    """
    from training import Cancelled

    cache = session.cache_dir(f"frames-{_digest(normalizer, config)}")
    paths = [cache / f"{x.id:06d}.npy" for x in logs]
    todo = [(x, p) for x, p in zip(logs, paths, strict=True) if not p.exists()]
    for done, (x, path) in enumerate(todo, start=1):
        if cancel():
            raise Cancelled("computing the frames was cancelled")
        frames = log_frames(session.rows(x.id), config, transform=normalizer)
        tmp = cache / f".{x.id:06d}.{uuid.uuid4().hex[:8]}.npy"  # another process may fill the same cache
        np.save(tmp, frames)
        os.replace(tmp, path)
        if progress:
            progress(done, len(todo))
    return [np.load(p, mmap_mode="r") for p in paths]


def spectral_features(
    session: Session, bundle: ModelBundle, logs: Sequence[LogInfo], config: SpectralConfig
) -> list[SpectralSteps]:
    """Per log, its per-step inputs (``(T, W·F)`` rows stacked from 5 Hz frames on demand).

    The frames are written once per input normalisation and front end (:func:`log_frame_files`), as ``.npy`` files
    memory-mapped on read: a 10-hour log at 100 Hz holds 180,000 rows, never its 3.6 million steps.
    """
    frames = log_frame_files(session, bundle.normalizer, logs, config)
    return [SpectralSteps(f, x.n_samples, config) for f, x in zip(frames, logs, strict=True)]


def in_memory_features(
    arrays: Sequence[np.ndarray], bundle: ModelBundle, config: SpectralConfig
) -> list[SpectralSteps] | list[RawSteps]:
    """Per-step inputs of raw ``(T, C)`` arrays outside a session (``classify``, evaluations): the front end's
    frames, or the windows a ``"windows"`` family's classifier reads."""
    if bundle.classifiers and bundle.stage2_family().stage2_inputs == "windows":
        length, hop = window_sizes(bundle)
        return [RawSteps(a, length=length, hop=hop, transform=bundle.normalizer) for a in arrays]
    return [SpectralSteps(log_frames(a, config, transform=bundle.normalizer), len(a), config) for a in arrays]


def input_span(classifier: ModelBundle | None, predictor: ModelBundle) -> int:
    """Samples one step's prediction reads: the front end's span for a frames family (1.6 s), a windows family's
    window; 0 for a classifier that reads stage 1's recurrent outputs (no fixed window) or none."""
    if classifier is None or not classifier.classifiers:
        return 0
    inputs = classifier.stage2_family().stage2_inputs
    if inputs == "frames":
        front = classifier.spectral or predictor.spectral
        return 0 if front is None else int(front.span)
    if inputs == "windows":
        return window_sizes(classifier)[0]
    return 0


def window_sizes(bundle: ModelBundle, front: SpectralConfig | None = None) -> tuple[int, int]:
    """A ``"windows"`` family's samples per window and between windows: its trained classifier's, else
    :data:`WINDOW_S` at the bundle's rate, every hop of the front end (``front``, else the bundle's)."""
    if bundle.classifiers and bundle.stage2_family().stage2_inputs == "windows":
        cfg = bundle.classifiers[0].config
        return int(cfg.length), int(cfg.hop)
    front = front or bundle.spectral
    hop = front.hop if front is not None else max(1, round(0.2 * bundle.rate_hz))
    return max(9, round(WINDOW_S * bundle.rate_hz)), hop


def window_features(
    session: Session, bundle: ModelBundle, logs: Sequence[LogInfo], sizes: tuple[int, int]
) -> list[RawSteps]:
    """Per log, a ``"windows"`` family's per-step inputs: the session's rows, read a slice at a time."""
    length, hop = sizes
    return [RawSteps(session.rows(x.id), length=length, hop=hop, transform=bundle.normalizer) for x in logs]


def free_stretches(
    length: int, change_points: np.ndarray, labelled: Sequence[tuple[int, int]], *, longest: int, shortest: int
) -> list[tuple[int, int]]:
    """Spans ``(start, stop)`` of one log with no label and no change point, at most ``longest`` samples (longer
    stretches cut into equal pieces), none shorter than ``shortest``."""
    edges = np.concatenate([np.asarray(change_points, np.int64), np.asarray(labelled, np.int64).reshape(-1)])
    return [
        (a, b)
        for a, b in labeling.spans(length, edges, max_len=longest, min_len=shortest)
        if not any(s < b and a < e for s, e in labelled)
    ]


def unlabelled_stretches(
    logs: Sequence[LogInfo],
    segments: Sequence[Segment],
    change_points: Callable[[LogInfo], np.ndarray],
    *,
    shortest: int,
) -> list[tuple[int, int, int]]:
    """Spans ``(log index, start, stop)`` of a session's logs with no label and no change point, cut to at most
    ``STRETCH_S`` (see :func:`free_stretches`).

    Self-training lends a stretch the terrain its frames agree on; a change point may be a change of terrain, and a
    labelled step is already known, so neither is inside one. Spans shorter than ``shortest`` (one summary window)
    are left out: no frame of theirs summarises them alone.
    """
    by_log: dict[int, list[tuple[int, int]]] = {}
    for s in segments:
        by_log.setdefault(s.log_id, []).append((s.start, s.stop))
    out = []
    for i, log in enumerate(logs):
        labelled = by_log.get(log.id, [])
        longest = max(shortest, int(STRETCH_S * log.rate_hz))
        spans = free_stretches(log.n_samples, change_points(log), labelled, longest=longest, shortest=shortest)
        out += [(i, a, b) for a, b in spans]
    return out


def stretch_units(stretches: Sequence[tuple[int, int, int]], change_points: Callable[[int], np.ndarray]) -> list[int]:
    """Per stretch ``(log index, start, stop)``, in the order :func:`unlabelled_stretches` gives them, the span
    between change points and labels it is a piece of (``change_points``: a log index's points). Self-training
    judges a span's pieces together (``WindowFitConfig.unit_agree``), so a 40 s span the model mostly calls grass
    lends grass to its 5 s pieces that alone were unsure."""
    units: list[int] = []
    unit, prev = -1, None
    points: dict[int, np.ndarray] = {}
    for i, a, b in stretches:
        if i not in points:
            points[i] = np.asarray(change_points(i))
        joined = prev == (i, a) and not bool((points[i] == a).any())
        unit += not joined
        units.append(unit)
        prev = (i, b)
    return units
