"""Sessions of demo walks for the Retrain benches: labels placed as a person answering suggestions would, and the
accuracy on every sample nobody labelled, against the walks' reference terrains."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from sessions import LogInfo, ModelVersion, Session
from training import TrainConfig
from workbench import cycle
from workbench.demo import generate_demo_logs

HIDDEN = 200  # both stages: the paper's width
STAGE1 = TrainConfig(max_epochs=1, patience=1)  # stage 1 of the setup: one epoch, as in bench_retrain
SETUP_LABELS, NEW_LABELS = 40, 10  # one-second stretches: labelled before the setup's training, then after it


def walk_session(folder: Path, *, n_logs: int, minutes: float) -> tuple[Session, list[LogInfo]]:
    """A session in ``folder`` of ``n_logs`` demo walks of ``minutes`` each, their reference terrains known."""
    t = time.perf_counter()
    files = generate_demo_logs(folder / "logs", n_logs=n_logs, minutes=minutes, seed=0)
    session = Session.create(folder / "session")
    logs = session.ingest(files)
    for name in {t for x in logs for _, _, t in session.reference(x.id)} - {t.name for t in session.terrains()}:
        session.add_terrain(name)
    total = sum(x.n_samples for x in logs)
    print(
        f"{len(logs)} walks, {total:,} steps ({total / logs[0].rate_hz / 60:.0f} min), setup "
        f"{time.perf_counter() - t:.0f} s",
        flush=True,
    )
    return session, logs


def label_stretches(session: Session, rng: np.random.Generator, n: int) -> None:
    """Label ``n`` one-second stretches at random places inside reference patches, as a person answering
    suggestions does; the terrains take turns so every one is labelled."""
    patches = [(x.id, a, b, t) for x in session.logs() for a, b, t in session.reference(x.id) if b - a >= 200]
    terrains = sorted({p[3] for p in patches})
    taken = {(s.log_id, s.start) for s in session.segments()}
    for i in range(n):
        mine = [p for p in patches if p[3] == terrains[i % len(terrains)]]
        while True:
            log_id, a, b, terrain = mine[rng.integers(len(mine))]
            start = int(rng.integers(a, b - 100)) // 100 * 100
            if (log_id, start) not in taken and start + 100 <= b:
                break
        taken.add((log_id, start))
        session.add_segment(log_id, start, start + 100, terrain, author="bench", source="manual")


def unlabelled_accuracy(session: Session, scores) -> float:
    """Per-timestep accuracy of the argmax on every sample nobody labelled, against the reference terrain."""
    hits = total = 0
    segments = session.segments()  # read once, not once per log
    for x in session.logs():
        truth = np.full(x.n_samples, "", dtype=object)
        for a, b, t in session.reference(x.id):
            truth[a:b] = t
        for s in segments:
            if s.log_id == x.id:
                truth[s.start : s.stop] = ""
        pred = np.asarray(scores.classes, dtype=object)[scores.scores[x.id].probs.argmax(axis=1)]
        keep = truth != ""
        hits += int((pred[keep] == truth[keep]).sum())
        total += int(keep.sum())
    return hits / max(total, 1)


def labelled_after_training(
    session: Session, rng: np.random.Generator, *, model: str, config: TrainConfig | None = None
) -> ModelVersion:
    """What a person did before pressing Retrain: ``SETUP_LABELS`` labels, both stages trained (stage 2 of family
    ``model``), then ``NEW_LABELS`` more labels. Returns the setup's classifier version."""
    label_stretches(session, rng, SETUP_LABELS)
    t = time.perf_counter()
    cycle.train_predictor(session, config=STAGE1, hidden=HIDDEN)
    setup = cycle.train_classifier(session, model=model, config=config, hidden=HIDDEN)
    print(f"setup models {time.perf_counter() - t:.0f} s", flush=True)
    label_stretches(session, rng, NEW_LABELS)
    return setup


def classified_walks(session: Session, predictions: Path) -> list[tuple[LogInfo, np.ndarray, np.ndarray]]:
    """Per log of ``session``, the terrain ``workbench classify`` predicted at each step (its CSV ``predictions``,
    column order) and the truth ``(T,)`` in the same indices: -1 where the reference says nothing, -2 for a terrain
    the model does not know (never right)."""
    import pandas as pd

    pred = pd.read_csv(predictions)
    classes = [c[2:] for c in pred.columns if c.startswith("p_")]
    out = []
    for log in session.logs():
        rows = pred[pred["log"] == log.name]
        predicted = rows[[f"p_{c}" for c in classes]].to_numpy().argmax(1)  # (T,)
        truth = np.full(log.n_samples, -1)
        for a, b, t in session.reference(log.id):
            truth[a:b] = classes.index(t) if t in classes else -2
        out.append((log, predicted, truth))
    return out
