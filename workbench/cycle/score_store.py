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
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import labeling
from sessions import Session, Terrain

from .scores import SessionScores, stage1_embedding

# 2: one .npy per array, memory-mapped when read (a fleet's hours of scores: gigabytes a zip would read whole)
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


def store_scores(session: Session, scores: SessionScores) -> Path | None:
    """Keep a complete scoring of the session (``compute_scores`` over every log) for the next start.

    Scores of older model versions are removed. Returns the folder, or ``None`` when there is nothing to keep.
    """
    if scores.predictor is None:
        return None
    folder = session.cache_dir(_folder_name(scores.predictor, scores.classifier))
    logs = {x.id: x.n_samples for x in session.logs()}
    names: dict[str, list[str]] = {}
    for log_id, s in scores.scores.items():
        arrays = {"surprise": np.asarray(s.surprise)}
        if s.probs is not None and s.disagreement is not None:
            arrays["probs"] = np.asarray(s.probs)
            arrays["disagreement"] = np.asarray(s.disagreement)
        if s.drift is not None:
            arrays["drift"] = np.asarray(s.drift)
        for kind, track in scores.tracks.get(log_id, {}).items():
            arrays[f"track.{kind}"] = np.asarray(track)
        for name, array in arrays.items():
            tmp = folder / f".{log_id:06d}.{name}.{uuid.uuid4().hex[:8]}.npy"
            with open(tmp, "wb") as f:
                np.save(f, array)
            os.replace(tmp, folder / f"{log_id:06d}.{name}.npy")
        names[str(log_id)] = sorted(arrays)
    meta = {
        "version": STORE_VERSION,
        "predictor": scores.predictor,
        "classifier": scores.classifier,
        "classes": list(scores.classes),
        "logs": {str(i): logs[i] for i in scores.scores if i in logs},
        "arrays": names,
    }
    for old in folder.glob("*.npz"):  # the first version's files: one zip per log
        old.unlink(missing_ok=True)
    _write_json(folder / META_FILE, meta)  # last: its presence marks the folder complete
    for other in folder.parent.glob("scores-p*"):
        if other != folder and other.is_dir():
            shutil.rmtree(other, ignore_errors=True)
    return folder


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
            z = {n: np.load(folder / f"{x.id:06d}.{n}.npy", mmap_mode="r") for n in meta["arrays"][str(x.id)]}
            has = "probs" in z  # stage 1 only: surprise alone
            scores[x.id] = labeling.LogScores(
                z["surprise"],
                z["probs"] if has else None,
                z["disagreement"] if has else None,
                z.get("drift"),
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
