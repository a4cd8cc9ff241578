"""Evaluation a user can run on their own logs: the session's recipe scored leave-logs-out against reference labels.

A model card's out-of-fold figure holds back labelled segments, but the other segments of the same log train the
fold model, and a log's neighbouring seconds look alike: that figure flatters. Here every fold holds out whole
logs: stage 2 trains on the labels of the other logs (stage 1, trained without labels on every log, is shared, as
the method prescribes), and the held-out logs are scored against reference labels the person gave as a file. The
reference is kept apart from the labels (the session's ``reference`` table, like BorealTC's folder names): it never
trains anything.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from sklearn.model_selection import KFold

from sessions import Session, WorkbenchError
from training import Family, TrainConfig, classification_metrics, family

from ..cycle import (
    STAGE1_FEATURES,
    active_predictor,
    classifier_family,
    front_end_of,
    model_logs,
    require_stage1,
    score_logs,
    signal_change_points,
    spectral_features,
    stage1_outputs,
    stage2_features,
    stretch_units,
    unlabelled_stretches,
    window_features,
    window_sizes,
)
from ..retrain import RETRAIN


def evaluate_session(
    session: Session,
    *,
    reference: Path | None = None,
    folds: int = 5,
    config: TrainConfig | None = None,
    seed: int = 0,
    log: Callable[[str], None] = print,
) -> str:
    """Score the session's recipe by held-out logs against its reference labels; returns a Markdown report.

    Args:
        session: The session, with a predictor, labels of at least two terrains, and reference labels.
        reference: A label file (CSV, Parquet, JSON: the columns of ``workbench labels export``) to store as the
            reference of the logs it names first; without it, the reference already in the session (e.g. from
            BorealTC folder names or demo sidecars).
        folds: Folds over the logs that have reference labels (at most one per log).
        config: Stage 2's training settings (default: the Retrain's, from scratch).
        seed: Seed of the fold split and of training.
        log: Where progress lines go.
    """
    if reference is not None:
        n = session.import_reference(reference)
        log(f"reference: {n} row(s) from {reference} (kept apart from labels)")
    # the reference is checked before the models: a person told to train first would then be told this
    _enough_reference([x for x in session.logs() if session.reference(x.id)], session.path)
    p_version, bundle = active_predictor(session)
    logs = model_logs(session, bundle.channels)
    classes = tuple(t.name for t in session.terrains())
    truth = {x.id: session.reference(x.id) for x in logs}
    judged = [i for i, x in enumerate(logs) if truth[x.id]]
    _enough_reference(judged, session.path)
    active = session.active_model("classifier")
    recipe = active.config if active is not None else {}
    fam = family(classifier_family(session))
    hidden = int(recipe.get("hidden", RETRAIN.hidden))
    feature_mode = recipe.get("feature_mode", STAGE1_FEATURES)
    config = replace(config or RETRAIN.classifier, seed=seed)
    window = replace(RETRAIN.window, seed=seed)
    front = front_end_of(session, bundle, logs) if fam.stage2_inputs in ("frames", "windows") else None
    if front is not None and fam.stage2_inputs == "windows":
        features = window_features(session, bundle, logs, window_sizes(bundle, front))
    elif front is not None:
        features = spectral_features(session, bundle, logs, front)
    else:
        require_stage1(session, fam, p_version, bundle)
        features = stage2_features(session, p_version, bundle, logs, feature_mode)
    outs = stage1_outputs(session, p_version, bundle, logs)
    index = {x.id: i for i, x in enumerate(logs)}

    def points_at(i: int) -> np.ndarray:
        return signal_change_points(session, logs[i])

    labels = [s for s in session.segments() if s.log_id in index]
    # stage 2 learns the labelled terrains only, as `workbench train` does: an output for a terrain nobody labelled
    # could only be wrong, and a short fit did predict one (outside every row of the confusion table)
    learned = tuple(c for c in classes if c in {s.terrain for s in labels})
    to_session = np.asarray([classes.index(c) for c in learned])  # a learned class's index among the terrains
    segments = [(index[s.log_id], s.start, s.stop, learned.index(s.terrain)) for s in labels]
    k = min(folds, len(judged))
    y_true, y_pred, rows = [], [], []
    unmeasured: dict[str, int] = {}  # reference samples of a terrain no fold could have predicted
    for fold, (_, held) in enumerate(KFold(k, shuffle=True, random_state=seed).split(judged), start=1):
        held_logs = {judged[j] for j in held}
        train = [s for s in segments if s[0] not in held_logs]
        if len({s[3] for s in train}) < 2:
            rows.append(
                f"| {fold} | {_names(logs, held_logs)} | – | labels of fewer than 2 terrains outside the fold |"
            )
            continue
        if front is not None:
            stretches, spans = [], {}
            if fam.self_training and window.self_training:
                # self-training reads the training logs' unlabelled stretches only: a held-out log stays unseen
                kept = [x for i, x in enumerate(logs) if i not in held_logs]
                pieces = unlabelled_stretches(
                    kept, labels, lambda x: signal_change_points(session, x), shortest=front.span
                )
                stretches = [(index[kept[j].id], a, b) for j, a, b in pieces]
                spans = {"units": stretch_units(stretches, points_at)} if window.unit_agree else {}
            fit = fam.fit(features, train, learned, config=window, stretches=stretches, **spans)
        else:
            fit = fam.fit(features, train, learned, config=config, hidden=hidden)
        order = sorted(held_logs)
        scored = score_logs(fit.models, [features[i] for i in order], [outs[logs[i].id].surprise() for i in order])
        fold_true, fold_pred = [], []
        trained = {int(to_session[s[3]]) for s in train}
        for i, s in zip(order, scored, strict=True):
            predicted = to_session[s.predicted]
            for a, b, terrain in truth[logs[i].id]:
                c = classes.index(terrain)
                if c not in trained:  # no label of it outside the fold: no model could be right; not a recall of 0
                    unmeasured[terrain] = unmeasured.get(terrain, 0) + b - a
                    continue
                fold_true.append(np.full(b - a, c))
                fold_pred.append(predicted[a:b])
        if not fold_true:
            rows.append(f"| {fold} | {_names(logs, held_logs)} | – | no reference terrain labelled outside the fold |")
            continue
        t, p = np.concatenate(fold_true), np.concatenate(fold_pred)
        y_true.append(t)
        y_pred.append(p)
        acc = float((t == p).mean())
        rows.append(f"| {fold} | {_names(logs, held_logs)} | {100 * acc:.2f} | {len(train)} labelled segments |")
        log(f"fold {fold}: {100 * acc:.2f} % on {len(held_logs)} held-out log(s)")
    if not y_true:
        raise WorkbenchError(f"{session.path}: no fold had labels of two terrains outside its held-out logs")
    m = classification_metrics(np.concatenate(y_true), np.concatenate(y_pred), classes)
    rate = logs[0].rate_hz
    # rows and columns of the terrains in use only: a session's other terrains are empty lines
    in_use = [c for c in classes if c in {t for x in judged for _, _, t in truth[logs[x].id]} | set(learned)]
    at = [classes.index(c) for c in in_use]
    reference_logs = {c: sum(any(t == c for _, _, t in truth[logs[x].id]) for x in judged) for c in in_use}
    recall_rows = []
    balanced = float(np.mean([m["per_class_recall"][c] for c in in_use if c in m["per_class_recall"]] or [np.nan]))
    for c in in_use:
        if c in m["per_class_recall"]:
            extra = f" ({unmeasured[c] / rate:.0f} s not measurable)" if c in unmeasured else ""
            recall_rows.append(f"| {c} | {100 * m['per_class_recall'][c]:.1f}{extra} |")
        elif c in unmeasured:
            recall_rows.append(
                f"| {c} | not measurable by held-out logs: reference in {reference_logs[c]} log(s), no label of it "
                "outside the fold that held them out |"
            )
    lines = [
        f"# Session {session.path.name}: leave-logs-out against reference labels",
        "",
        f"Recipe: the active predictor v{p_version.id}; {_recipe(fam, hidden, feature_mode)}, retrained "
        f"per fold on the other logs' labels. {len(judged)} logs with reference, {k} folds, "
        f"{m['n'] / rate:.0f} s of reference time scored.",
        "",
        f"Scored {m['n']} reference samples; {sum(unmeasured.values())} not measurable (a terrain with no label "
        "outside the fold that held its log out: no model there could name it).",
        "",
        "| fold | held-out logs | accuracy (%) | trained on |",
        "| --- | --- | --- | --- |",
        *rows,
        "",
        f"**Accuracy {100 * m['accuracy']:.2f} %, balanced {100 * balanced:.2f} %, macro-F1 {m['macro_f1']:.3f}** "
        "over the held-out reference time of terrains labelled outside its fold (balanced: the mean of the "
        "terrains' recalls).",
        "",
        _majority_line(np.concatenate(y_true), classes, float(m["accuracy"])),
        "",
        "| terrain | recall (%) |",
        "| --- | --- |",
        *recall_rows,
        "",
        "Confusion (rows: reference, columns: predicted; samples; the terrains in the reference or the labels):",
        "",
        "| | " + " | ".join(in_use) + " |",
        "| --- | " + " | ".join("---" for _ in in_use) + " |",
        *(
            f"| {c} | " + " | ".join(str(m["confusion"][i][j]) for j in at) + " |"
            for c, i in zip(in_use, at, strict=True)
        ),
    ]
    return "\n".join(lines) + "\n"


def _majority_line(truth: np.ndarray, classes: Sequence[str], accuracy: float) -> str:
    """Always answering the most common terrain of the time scored: the baseline a model must beat."""
    counts = np.bincount(truth.astype(np.int64), minlength=len(classes))
    share = counts.max() / max(len(truth), 1)
    below = "; **the model is no better**" if accuracy <= share else ""
    return f"Always the most common terrain ({classes[int(counts.argmax())]}): {100 * share:.2f} %{below}."


def _enough_reference(judged: Sequence[object], path: Path) -> None:
    if len(judged) < 2:
        raise WorkbenchError(
            f"{path}: {len(judged)} log(s) have reference labels; held-out logs need at least 2 "
            "(give them with --reference FILE)"
        )


def _recipe(fam: Family, hidden: int, feature_mode: str) -> str:
    if fam.stage2_inputs in ("frames", "windows"):
        return f"stage 2 of the {fam.name} family ({fam.summary})"
    return f"stage 2 of the {fam.name} family (LSTM of {hidden} units on `{feature_mode}` features)"


def _names(logs, held: set[int]) -> str:
    names = [logs[i].name for i in sorted(held)]
    return ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
