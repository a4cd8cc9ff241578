"""The last scoring and suggestion queue, kept in the session so that the page draws them at once when it opens.

Scoring every log is the slow part of opening a session (the demo's 30 minutes of logs: 2 s; a fleet's hours:
minutes), and between two starts of the server nothing it depends on has usually changed. What is stored is keyed
by what it was computed from: the active predictor and classifier versions, each log's length, and for the queue
the labels and the ranking strategy. Anything else makes it stale, and the worker computes it again as before.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

import labeling
from sessions import LogInfo, Session, Terrain

from .forked_scores import rank_tracks, scored_forked, scoring_processes
from .score_files import (
    GROUP_STEPS,
    GroupFirst,
    Scored,
    kept_array,
    kept_scores,
    log_groups,
    score_arrays,
    write_array,
)
from .scores import TRACK_WINDOW, SessionScores, stage1_embedding

# 2: one .npy per array, memory-mapped when big (a fleet's hours of scores: gigabytes a zip would read whole)
STORE_VERSION = 2
META_FILE = "meta.json"
QUEUE_FILE = "queue.json"


@dataclass(frozen=True)
class StoredScores:
    """Scores read back from the session.

    Attributes:
        scores: The stored scores, for the logs that are still in the session with the same length.
        complete: Every log the active models cover is among them; otherwise the worker scores the session again.
    """

    scores: SessionScores
    complete: bool


def _active_versions(session: Session) -> tuple[int, int | None] | None:
    p = session.active_model("predictor")
    if p is None:
        return None
    c = session.active_model("classifier")
    if c is not None and c.config.get("predictor") != p.id:
        c = None  # compute_scores ignores a classifier trained on another predictor's features: so does the store
    return p.id, None if c is None else c.id


def _folder_name(predictor: int, classifier: int | None) -> str:
    return f"scores-p{predictor:04d}-c{classifier or 0:04d}"


def _write_json(path: Path, value: object) -> None:
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}")
    tmp.write_text(json.dumps(value))
    os.replace(tmp, path)  # whole or not at all: a reader never sees half a file


def _finish_store(session: Session, folder: Path, scores: SessionScores, names: dict[str, list[str]]) -> None:
    """Write the folder's meta last (its presence marks the folder complete) and remove older versions' scores."""
    logs = {x.id: x.n_samples for x in session.logs()}
    meta = {
        "version": STORE_VERSION,
        "predictor": scores.predictor,
        "classifier": scores.classifier,
        "classes": list(scores.classes),
        "span": scores.span,
        "logs": {str(i): logs[i] for i in scores.scores if i in logs},
        "arrays": names,
    }
    for old in folder.glob("*.npz"):  # the first version's files: one zip per log
        old.unlink(missing_ok=True)
    for half in folder.glob(".*.npy"):  # a forked scorer's array cut short when its scoring was stopped
        half.unlink(missing_ok=True)
    _write_json(folder / META_FILE, meta)
    for other in folder.parent.glob("scores-p*"):
        if other != folder and other.is_dir():
            shutil.rmtree(other, ignore_errors=True)


def store_scores(session: Session, scores: SessionScores) -> Path | None:
    """Keep a complete scoring of the session (``compute_scores`` over every log) for the next start.

    Scores of older model versions are removed. Returns the folder, or ``None`` when there is nothing to keep.
    """
    if scores.predictor is None:
        return None
    folder = session.cache_dir(_folder_name(scores.predictor, scores.classifier))
    names: dict[str, list[str]] = {}
    for log_id, s in scores.scores.items():
        arrays = score_arrays(s)
        for kind, track in scores.tracks.get(log_id, {}).items():
            arrays[f"track.{kind}"] = np.asarray(track)
        for name, array in arrays.items():
            write_array(folder, log_id, name, array)
        names[str(log_id)] = sorted(arrays)
    _finish_store(session, folder, scores, names)
    return folder


def score_and_store(
    session: Session,
    *,
    score: Callable[..., SessionScores],
    run: Callable[..., Any] = lambda fn, *a, **k: fn(*a, **k),
    stop: Callable[[], bool] = lambda: False,
    window: int = TRACK_WINDOW,
    group_steps: int = GROUP_STEPS,
    on_error: Callable[[str], None] = print,
    jobs: int | None = None,
) -> SessionScores | None:
    """Score every log a group at a time, each group's scores written to the kept files as it is scored and held
    memory-mapped, then the tracks ranked over the whole session, one kind at a time, and kept too.

    Scoring every log in one call held every log's per-step scores at once (at 100 hours of logs, 6.4 GiB of the
    process's own memory) and took the server's torch lane for twenty minutes; a group of logs takes it for
    seconds, and other work (a Retrain, a page's request) goes between two groups.

    Args:
        score: ``compute_scores`` (or what stands for it): called as ``score(session, log_ids=..., tracks=False)``.
        run: How each group's scoring runs (the server's torch lane: ``LANE.run``).
        stop: Polled between groups; ``None`` is returned when it says so, or when the active models changed
            (a Retrain ended meanwhile: its scores are wanted instead).
        window: The tracks' smoothing, in samples.
        group_steps: Samples of logs scored together (at least one log).
        on_error: Told when the scores cannot be written (a full disk): every log is then scored in memory, as
            before, and the next start scores them again.
        jobs: Processes to score in (``None``: :func:`.forked_scores.scoring_processes`, one per core where the
            logs are hours long); with more than one, the groups are scored in forked children, a few per child,
            and ``score`` runs there.

    Returns:
        The scores of every log, their arrays memory-mapped from the session's kept scores; ``None`` when stopped.
    """
    try:
        return _score_and_store(session, score, run, stop, window, group_steps, jobs)
    except OSError as exc:  # a full disk costs the next start its head start, nothing more
        on_error(f"could not keep the scores for the next start: {exc}")
        return run(score, session, window=window)


def _score_and_store(
    session: Session,
    score: Callable[..., SessionScores],
    run: Callable[..., Any],
    stop: Callable[[], bool],
    window: int,
    group_steps: int,
    jobs: int | None,
) -> SessionScores | None:
    from training import load_bundle

    from .train_stages import model_logs

    versions = _active_versions(session)
    p_version = session.active_model("predictor")
    if versions is None or p_version is None:
        return run(score, session, window=window)  # nothing trained: nothing to keep
    logs = model_logs(session, load_bundle(session.path / p_version.path).channels)
    folder = session.cache_dir(_folder_name(*versions))
    (folder / META_FILE).unlink(missing_ok=True)  # incomplete until every log is written again
    processes = scoring_processes(logs) if jobs is None else max(1, min(jobs, len(logs)))

    def cancel() -> bool:
        return stop() or _active_versions(session) != versions

    if processes > 1:
        scored = scored_forked(session, logs, score, run, cancel, versions, folder, window, group_steps, processes)
    else:
        scored = _scored_here(session, logs, score, run, stop, versions, folder, window, group_steps)
    if scored is None:  # stopped
        return None
    first, scores, embeddings, names = scored
    if first is None:  # no log to score
        return run(score, session, window=window)
    ids = [x.id for x in logs if x.id in scores]
    tracks: dict[int, dict[str, np.ndarray]] = {i: {} for i in ids}
    ranked = rank_tracks(session, folder, ids, scores, run, stop, window, processes)
    if ranked is None:
        return None
    for kind, has in zip(labeling.KINDS, ranked, strict=True):
        for i in has:
            tracks[i][kind] = kept_array(folder / f"{i:06d}.track.{kind}.npy")
            names[str(i)].append(f"track.{kind}")
    result = SessionScores(
        first.predictor,
        first.classifier,
        first.classes,
        {i: scores[i] for i in ids},
        tracks,
        {i: embeddings[i] for i in ids},
        window,
        first.span,
    )
    _finish_store(session, folder, result, {k: sorted(v) for k, v in names.items()})
    return result


def _scored_here(
    session: Session,
    logs: Sequence[LogInfo],
    score: Callable[..., SessionScores],
    run: Callable[..., Any],
    stop: Callable[[], bool],
    versions: tuple[int, int | None],
    folder: Path,
    window: int,
    group_steps: int,
) -> Scored | None:
    """Each group scored in this process through ``run``, written, and dropped before the next."""
    first: GroupFirst | None = None
    scores: dict[int, labeling.LogScores] = {}
    embeddings: dict = {}
    names: dict[str, list[str]] = {}
    for group in ([x.id for x in g] for g in log_groups(logs, group_steps=group_steps)):
        if stop() or _active_versions(session) != versions:
            return None
        part = run(score, session, log_ids=group, window=window, tracks=False)
        if (part.predictor, part.classifier) != versions:
            return None
        first = first or GroupFirst(part.predictor, part.classifier, tuple(part.classes), part.span)
        embeddings.update(part.embeddings)
        for log_id, s in part.scores.items():
            kept = {n: write_array(folder, log_id, n, a) for n, a in score_arrays(s).items()}
            scores[log_id] = kept_scores(kept)
            names[str(log_id)] = sorted(kept)
        del part
    return first, scores, embeddings, names  # first None: no log to score


def stored_scores(session: Session) -> StoredScores | None:
    """The stored scoring of the active models, or ``None`` when there is none (or it is unreadable).

    The arrays are memory-mapped (read-only): the first screen reads the pages it draws, not every log's scores
    (10 h of logs: 1.7 s to read them whole). The suggestions' embeddings are rebuilt from the stage-1 cache,
    memory-mapped too; when that cache is gone the stored scores are not used, since rebuilding it is the slow part
    anyway.
    """
    from training import load_bundle

    from .stage_inputs import stage1_cached, stage1_outputs
    from .train_stages import model_logs

    versions = _active_versions(session)
    if versions is None:
        return None
    folder = session.cache_dir(_folder_name(*versions))
    try:
        meta = json.loads((folder / META_FILE).read_text())
    except (OSError, ValueError):
        return None
    if meta.get("version") != STORE_VERSION:
        return None
    p_version = session.active_model("predictor")
    assert p_version is not None
    try:
        bundle = load_bundle(session.path / p_version.path)
        wanted = model_logs(session, bundle.channels)
    except Exception:  # a damaged model: the worker's full scoring says so in one line
        return None
    stored = {int(k): int(v) for k, v in meta.get("logs", {}).items()}
    logs = [x for x in wanted if stored.get(x.id) == x.n_samples]
    if not logs or not stage1_cached(session, p_version, logs):
        return None
    scores: dict[int, labeling.LogScores] = {}
    tracks: dict[int, dict[str, np.ndarray]] = {}
    try:
        for x in logs:
            z = {n: kept_array(folder / f"{x.id:06d}.{n}.npy") for n in meta["arrays"][str(x.id)]}
            has = "probs" in z  # stage 1 only: surprise alone
            scores[x.id] = labeling.LogScores(
                z["surprise"],
                z["probs"] if has else None,
                z["disagreement"] if has else None,
                z.get("drift"),
                z.get("agreement") if has else None,  # none in scores kept before it was: the drift's figure then
            )
            tracks[x.id] = {k.split(".", 1)[1]: v for k, v in z.items() if k.startswith("track.")}
    except (OSError, ValueError, KeyError, TypeError):
        return None
    outs = stage1_outputs(session, p_version, bundle, logs)  # cached: memory maps only
    result = SessionScores(
        versions[0],
        versions[1],
        tuple(meta.get("classes", ())),
        scores,
        tracks,
        {x.id: stage1_embedding(outs[x.id]) for x in logs},
        span=int(meta.get("span", 0)),
    )
    return StoredScores(result, complete=len(logs) == len(wanted))


def queue_key(session: Session, strategy: str, terrains: Sequence[Terrain]) -> str:
    """What a suggestion queue depends on besides the scores: every label, the terrains and the ranking strategy."""
    h = hashlib.sha256(f"{strategy}|{','.join(t.name for t in terrains)}|".encode())
    for s in session.segments():
        h.update(f"{s.id},{s.log_id},{s.start},{s.stop},{s.terrain};".encode())
    return h.hexdigest()[:16]


def store_queue(session: Session, scores: SessionScores, rows: Sequence[tuple], *, key: str) -> None:
    """Keep the queue computed from ``scores``: rows of ``(log id, start, stop, reason, guess, score, kind)``."""
    if scores.predictor is None:
        return
    folder = session.cache_dir(_folder_name(scores.predictor, scores.classifier))
    if not (folder / META_FILE).exists():  # the scores it was ranked from were not stored (a partial scoring)
        return
    _write_json(folder / QUEUE_FILE, {"key": key, "rows": [list(r) for r in rows]})


def stored_queue(session: Session, scores: SessionScores, *, key: str) -> list[tuple] | None:
    """The stored queue ranked from ``scores`` under ``key``, or ``None`` when it is stale or absent."""
    if scores.predictor is None:
        return None
    path = session.cache_dir(_folder_name(scores.predictor, scores.classifier)) / QUEUE_FILE
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if data.get("key") != key:
        return None
    rows = [tuple(r) for r in data.get("rows", [])]
    if any(len(r) not in (6, 7) or r[0] not in scores.scores for r in rows):  # 6: kept before spot checks
        return None
    return rows
