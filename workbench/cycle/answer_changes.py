"""What the last Retrain changed: the share of the time nobody labelled where the new version's answer differs from
the one before it. Wherever the two agree, both are right or both wrong there, so the session's accuracy moved by at
most that share, either way: a bound that needs no check, for a person deciding whether another round is worth it.

Each classifier version's answers (its most probable terrain per step, one byte a step) are kept in the session's
cache when its scores are computed, the last three versions only; derived, so a deleted cache costs the comparison
until the next two scorings, nothing more.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from sessions import Session

from .checks_record import names_now
from .scores import SessionScores

PREFIX = "answers-c"
# versions whose answers are kept: the active one, and the one before it on other labels (a Retrain saves a quick
# fine-tune and then the version from scratch on the same labels)
KEEP = 3


@dataclass(frozen=True)
class AnswerChange:
    """How much of the time nobody labelled changed answer between two classifier versions.

    Attributes:
        before: The earlier version.
        after: The later (the scores') version.
        changed: The share of that time whose answer changed, in [0, 1]: the session moved by at most this.
        steps: How many steps that time holds.
        labels: Labels made between the two versions.
    """

    before: int
    after: int
    changed: float
    steps: int
    labels: int

    def words(self) -> str:
        """``"the last Retrain (v5 → v6, 12 labels) changed the model's answer on 0.8 % of the time nobody
        labelled: the session moved by at most 0.8 points either way"``."""
        labels = f", {self.labels} label{'s' if self.labels != 1 else ''}" if self.labels else ""
        pct = 100 * self.changed
        return (
            f"the last Retrain (v{self.before} → v{self.after}{labels}) changed the model's answer on {pct:.1f} % of "
            f"the time nobody labelled: the session moved by at most {pct:.1f} points either way"
        )


def _folder(session: Session, version: int):
    return session.path / "cache" / f"{PREFIX}{version:04d}"


def keep_answers(session: Session, scores: SessionScores) -> None:
    """Keep the scores' classifier's answers per log (terrain names beside them), and drop all but the last
    ``KEEP`` versions'. A full disk costs the comparison, nothing else."""
    if scores.classifier is None:
        return
    try:
        folder = session.cache_dir(f"{PREFIX}{scores.classifier:04d}")
        for log_id, s in scores.scores.items():
            if s.probs is None:
                continue
            answers = np.asarray(s.probs).argmax(axis=1).astype(np.uint8)  # (T,) at most 255 terrains
            tmp = folder / f".{log_id}.{uuid.uuid4().hex[:8]}.npy"
            np.save(tmp, answers)
            os.replace(tmp, folder / f"{log_id}.npy")
        names = folder / "classes.txt"
        tmp = folder / f".classes.{uuid.uuid4().hex[:8]}"
        tmp.write_text("\n".join(names_now(session, scores)))
        os.replace(tmp, names)
        kept = sorted((session.path / "cache").glob(f"{PREFIX}*"))
        for old in kept[:-KEEP]:
            shutil.rmtree(old, ignore_errors=True)
    except OSError:
        return


def answer_change(
    session: Session, scores: SessionScores, *, log_ids: Collection[int] | None = None
) -> AnswerChange | None:
    """The share of the time nobody labelled whose answer the scores' version changed from the version before it:
    the newest earlier version whose answers are kept and which was trained on other labels (a Retrain's quick
    fine-tune is on the same labels as the version from scratch after it); over the logs ``log_ids`` only, when
    given; ``None`` without such a version."""
    if scores.classifier is None:
        return None
    versions = {v.id: v for v in session.model_versions("classifier")}
    after = versions.get(scores.classifier)
    if after is None:
        return None

    def labels_of(v) -> tuple:
        return (v.metrics.get("n_segments"), round(float(v.metrics.get("labelled_seconds") or 0.0), 3))

    earlier = [
        int(p.name.removeprefix(PREFIX))
        for p in (session.path / "cache").glob(f"{PREFIX}*")
        if p.name.removeprefix(PREFIX).isdigit() and int(p.name.removeprefix(PREFIX)) < scores.classifier
    ]
    earlier = [v for v in earlier if v in versions and labels_of(versions[v]) != labels_of(after)]
    if not earlier:
        return None
    before = max(earlier)
    folder = _folder(session, before)
    try:
        old_names = (folder / "classes.txt").read_text().split("\n")
    except OSError:
        return None
    names = names_now(session, scores)
    # an earlier version's class as the session calls terrains now (renamed or not), then as the scores' index
    made = versions[before].created_at
    renamed = session.terrain_names_since(made)
    index = np.array([names.index(renamed.get(c, c)) if renamed.get(c, c) in names else -1 for c in old_names])
    spans: dict[int, list[tuple[int, int]]] = {}
    for g in session.segments():
        spans.setdefault(g.log_id, []).append((g.start, g.stop))
    changed = steps = 0
    for log_id, s in scores.scores.items():
        path = folder / f"{log_id}.npy"
        if s.probs is None or not path.exists() or (log_ids is not None and log_id not in log_ids):
            continue
        try:
            old = np.load(path, mmap_mode="r")
        except (OSError, ValueError):
            continue
        if len(old) != len(s.probs):
            continue
        free = np.ones(len(old), bool)  # (T,) the time nobody labelled
        for a, b in spans.get(log_id, ()):
            free[a:b] = False
        now = np.asarray(s.probs).argmax(axis=1)[free]
        changed += int((index[np.asarray(old)[free]] != now).sum())
        steps += int(free.sum())
    if not steps:
        return None
    labels = sum(1 for g in session.segments() if made < g.created_at <= after.created_at)
    return AnswerChange(before, scores.classifier, changed / steps, steps, labels)
