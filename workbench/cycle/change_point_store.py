"""Each log's change points (:func:`log_change_points`), kept in the session per predictor, so that a restart does
not find them again.

The suggestion queue cuts every log at its change points, found over the log's channels and its stage-1 surprise:
at 100 hours of logs, 25 s of the worker's time before the first queue after a restart could be ranked, and again
after every start. They depend on the log's samples (never changed) and the predictor's surprise, so they are kept
per predictor version; a new predictor's folder replaces the old one.
"""

from __future__ import annotations

import os
import shutil
import uuid
from pathlib import Path

import numpy as np

import labeling
from sessions import LogInfo, Session


def log_change_points(samples: np.ndarray, surprise: np.ndarray | None, *, rate_hz: float) -> np.ndarray:
    """Change points (sample indices) of one log over its z-scored channels and, when known, its surprise."""
    x = np.asarray(samples, np.float32)
    z = (x - x.mean(axis=0)) / (x.std(axis=0) + 1e-6)  # (T, C)
    if surprise is not None:
        z = np.column_stack([z, surprise])
    return labeling.change_points(z, block=max(1, round(0.25 * rate_hz)))


def _folder(session: Session, predictor: int) -> Path:
    return session.cache_dir(f"changepoints-p{predictor:04d}")


def _file(folder: Path, log: LogInfo) -> Path:
    return folder / f"{log.id:06d}-{log.n_samples}.npy"  # a log ingested again with another length is another file


def kept_change_points(session: Session, predictor: int, log: LogInfo) -> np.ndarray | None:
    """The change points kept for ``log`` under ``predictor``, or ``None`` when none are (or they cannot be read)."""
    path = _file(_folder(session, predictor), log)
    if not path.exists():
        return None
    try:
        return np.load(path).astype(np.int64)
    except (OSError, ValueError):  # a damaged file is found again, never a reason to fail
        return None


def keep_change_points(session: Session, predictor: int, log: LogInfo, points: np.ndarray) -> None:
    """Keep ``log``'s change points under ``predictor``; other predictors' are removed."""
    folder = _folder(session, predictor)
    tmp = folder / f".{log.id:06d}.{uuid.uuid4().hex[:8]}.npy"
    np.save(tmp, np.asarray(points, np.int64))
    os.replace(tmp, _file(folder, log))  # whole or not at all
    for other in folder.parent.glob("changepoints-p*"):
        if other != folder and other.is_dir():
            shutil.rmtree(other, ignore_errors=True)
