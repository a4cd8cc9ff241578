"""Stage 2 training: the classifier on frozen stage-1 features, from labelled segments only, as a k-fold ensemble."""

from __future__ import annotations

import copy
import time
from collections.abc import Sequence

import numpy as np
import torch

from ..figures import classification_metrics
from ..fitting import ClassifierFit, Segment, fold_indices
from ..running import CancelFn, Cancelled, Progress, ProgressFn, never
from .lstm_config import ClassifierConfig, TrainConfig
from .lstm_losses import classifier_loss, consistency_loss, masked_cross_entropy
from .lstm_models import Classifier, feature_moments
from .pieces import Piece, labelled_pieces, stage2_batch

MIN_BATCH = 32
MAX_STEPS = 4
CONSISTENCY_PAIRS = 32  # per step: 64 more windows; 3-4x the stage-2 time on BorealTC, 15x on long demo walks


def length_batches(lengths: np.ndarray, batch: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Indices ``(n,)`` of pieces in batches of about equal length, the batches in random order.

    A batch is padded to its longest piece and the LSTM steps through every padded step, so mixing 100- and
    660-step pieces wastes up to half the work. The lengths get up to 10 % of random jitter before sorting, so the
    batches are not the same every epoch.
    """
    jittered = lengths * (1.0 + 0.1 * rng.random(len(lengths)))
    order = np.argsort(jittered, kind="stable")
    groups = [order[i : i + batch] for i in range(0, len(order), batch)]
    return [groups[i] for i in rng.permutation(len(groups))]


def random_crops(segments: Sequence[Segment], config: TrainConfig, rng: np.random.Generator) -> list[Piece]:
    """Windows of ``label_piece`` samples at random places in each segment (as many as fit), with context."""
    out = []
    for seq, start, stop, label in segments:
        n = stop - start
        count = -(-n // config.label_piece)
        for _ in range(count):
            length = min(n, config.label_piece)
            a = start + int(rng.integers(0, n - length + 1))
            out.append(Piece(seq, max(0, a - config.context), a + length, a, label))
    return out


def _epoch_pieces(
    segments: Sequence[Segment], replay: Sequence[Segment], config: TrainConfig, rng: np.random.Generator
) -> list[Piece]:
    """One epoch's crops of ``segments`` plus as many crops of ``replay`` drawn at random (at least a batch); none
    at all when ``segments`` is empty, since there is nothing new to learn."""
    out = random_crops(segments, config, rng)
    if out and replay:
        old = random_crops(replay, config, rng)
        take = min(len(old), max(len(out), MIN_BATCH))
        out += [old[i] for i in rng.choice(len(old), take, replace=False)]
    return out


def balanced_weights(segments: Sequence[Segment], n_classes: int) -> np.ndarray:
    """``(K,)`` class weights inverse to each class's labelled steps, scaled so a labelled step weighs 1 on average.

    A class with no labels gets weight 0 (it has no steps to weigh).
    """
    steps = np.zeros(n_classes)
    for _, start, stop, label in segments:
        steps[label] += stop - start
    present = steps > 0
    w = np.zeros(n_classes)
    w[present] = steps[present].sum() / (present.sum() * steps[present])
    return w


def _ce(
    model: Classifier,
    features: Sequence[np.ndarray],
    pieces: list[Piece],
    batch: int,
    dev: str,
    weight: torch.Tensor | None,
) -> float:
    total, count = 0.0, 0.0
    with torch.inference_mode():
        for i in range(0, len(pieces), batch):
            f, labels, mask = (torch.from_numpy(a).to(dev) for a in stage2_batch(features, pieces[i : i + batch]))
            logits, _ = model(f)
            m = mask.float() if weight is None else mask.float() * weight[labels.clamp_min(0)]
            n = float(m.sum())
            total += float(masked_cross_entropy(logits, labels, mask, weight)) * n
            count += n
    return total / max(count, 1e-12)


def _consistency(
    model: Classifier,
    features: Sequence[np.ndarray],
    pairs: Sequence[tuple[Piece, Piece]],
    rng: np.random.Generator,
    dev: str,
) -> torch.Tensor:
    """The consistency term on ``CONSISTENCY_PAIRS`` pairs drawn at random (all of them when fewer)."""
    take = rng.choice(len(pairs), min(len(pairs), CONSISTENCY_PAIRS), replace=False)
    group = [pairs[i][0] for i in take] + [pairs[i][1] for i in take]
    f = torch.from_numpy(stage2_batch(features, group)[0]).to(dev)  # (2P, T, F)
    logits, _ = model(f)  # (2P, T, K)
    last = torch.as_tensor([p.length - 1 for p in group], device=dev)  # (2P,)
    return consistency_loss(logits, last)


def _predict_whole_logs(
    model: Classifier, features: Sequence[np.ndarray], segments: Sequence[Segment], dev: str
) -> tuple[np.ndarray, np.ndarray]:
    """Labels and predictions at ``segments``' steps from one pass over each whole log, as the model is used."""
    from ..passes import run_classifiers

    logs = sorted({s[0] for s in segments})
    probs = run_classifiers([model], [features[i] for i in logs], device=dev)
    by_log = dict(zip(logs, probs, strict=True))
    y_true = [np.full(stop - start, label) for _, start, stop, label in segments]
    y_pred = [by_log[seq][0, start:stop].argmax(-1) for seq, start, stop, _ in segments]
    return np.concatenate(y_true), np.concatenate(y_pred)


def fit_classifier(
    features: Sequence[np.ndarray],
    segments: Sequence[Segment],
    classes: Sequence[str],
    *,
    config: TrainConfig | None = None,
    hidden: int = 200,
    dropout: float = 0.2,
    init: Sequence[Classifier] | None = None,
    new: Sequence[int] | None = None,
    pairs: Sequence[tuple[Piece, Piece]] = (),
    progress: ProgressFn | None = None,
    cancel: CancelFn = never,
) -> ClassifierFit:
    """Train the k fold models on labelled segments of frozen stage-1 features.

    Args:
        features: Per log, ``(T, F)`` stage-1 features (from the cache). The classifier standardises its inputs
            with their moments over all of these, labelled or not.
        segments: Labelled stretches ``(log index, start, stop, class index)``.
        classes: The ``K`` class names.
        config: Training settings; ``k_folds`` folds over segments.
        hidden: LSTM width.
        dropout: Dropout after each LSTM layer.
        init: Previous fold models to warm-start from (used when shapes match).
        new: With ``init``: indices into ``segments`` of those the previous models did not train on. Each epoch
            then trains on the new segments and as many old ones drawn at random (replay), not on every label: the
            old models already fit the old labels, and a fine-tune's time follows the new ones. A fold with no new
            segment in its training part keeps its previous model.
        pairs: Unlabelled windows of ``features`` that should get the same class (``data.neighbour_pairs``). Every
            step adds ``config.consistency`` × ``losses.consistency_loss`` over ``CONSISTENCY_PAIRS`` of them drawn
            at random. Empty: labels alone.
        progress: Called after every optimiser step.
        cancel: Polled after every step.

    Returns:
        The ensemble and out-of-fold metrics: each labelled step predicted, in a pass over its whole log, by the
        fold model that did not train on it.
    """
    if not segments:
        raise ValueError("no labelled segments to train the classifier on")
    config = config or TrainConfig()
    torch.manual_seed(config.seed)
    rng = np.random.default_rng(config.seed)
    dev = config.device
    cfg = ClassifierConfig(features[0].shape[1], len(classes), hidden, dropout)
    folds = fold_indices([s[3] for s in segments], config.k_folds, config.seed)
    moments = feature_moments(features)  # over every log given, labelled or not: no labels needed
    weight = None
    if config.class_balance:
        weight = torch.as_tensor(balanced_weights(segments, len(classes)), dtype=torch.float32, device=dev)
    models, histories, oof_true, oof_pred = [], [], [], []
    t0 = time.monotonic()
    for f_i, (train_idx, val_idx) in enumerate(folds, start=1):

        def pieces(idx: np.ndarray) -> list[Piece]:
            return labelled_pieces([segments[i] for i in idx], piece=config.label_piece, context=config.context)

        train_segments = [segments[i] for i in train_idx]
        val = pieces(val_idx)
        model = Classifier(cfg)
        warm = init is not None and len(init) >= f_i and init[f_i - 1].config == cfg
        if warm:
            model.load_state_dict(init[f_i - 1].state_dict())
        model.set_standardisation(*moments)
        model.to(dev)
        optimizer = torch.optim.Adam(model.parameters(), lr=config.lr)
        old_segments: list[Segment] = []
        if warm and new is not None:
            fresh = set(new)
            old_segments = [segments[i] for i in train_idx if i not in fresh]
            train_segments = [segments[i] for i in train_idx if i in fresh]
        n_pieces = len(_epoch_pieces(train_segments, old_segments, config, rng))
        # A step costs about the same at batch 1 as at 32 (the LSTM's sequential length dominates on a CPU), so
        # small batches only multiply time; up to MAX_STEPS steps per epoch, at most the paper's batch of 512.
        batch = min(config.batch_size, max(MIN_BATCH, -(-n_pieces // MAX_STEPS)))
        steps = -(-n_pieces // batch)
        best, best_state, since, history = float("inf"), copy.deepcopy(model.state_dict()), 0, []
        for epoch in range(1, config.max_epochs + 1):
            model.train()
            train = _epoch_pieces(train_segments, old_segments, config, rng)  # fresh crops every epoch
            batches = length_batches(np.array([p.length for p in train], np.float64), batch, rng)
            total = 0.0
            for step, idx in enumerate(batches):
                group = [train[i] for i in idx]
                f, labels, mask = (torch.from_numpy(a).to(dev) for a in stage2_batch(features, group))
                logits, _ = model(f)  # (B, T, K)
                loss = classifier_loss(logits, labels, mask, model.lstm, config.elastic, weight)
                if pairs and config.consistency > 0:
                    loss = loss + config.consistency * _consistency(model, features, pairs, rng, dev)
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(model.parameters(), config.clip)
                optimizer.step()
                total += loss.item()
                if cancel():
                    raise Cancelled("classifier training cancelled")
                if progress:
                    progress(
                        Progress(
                            "classifier",
                            f_i,
                            len(folds),
                            epoch,
                            config.max_epochs,
                            step + 1,
                            steps,
                            total / (step + 1),
                            history[-1]["val_loss"] if history else None,
                            None if best == float("inf") else best,
                            time.monotonic() - t0,
                        )
                    )
            model.eval()
            val_loss = _ce(model, features, val, config.batch_size, dev, weight)
            history.append({"epoch": epoch, "train_loss": total / max(steps, 1), "val_loss": val_loss})
            if val_loss < best - 1e-6:
                best, best_state, since = val_loss, copy.deepcopy(model.state_dict()), 0
            else:
                since += 1
            if since >= config.patience:
                break
        model.load_state_dict(best_state)
        model.eval()
        y_true, y_pred = _predict_whole_logs(model, features, [segments[i] for i in val_idx], dev)
        oof_true.append(y_true)
        oof_pred.append(y_pred)
        models.append(model.cpu())
        histories.append(history)
    metrics = classification_metrics(np.concatenate(oof_true), np.concatenate(oof_pred), classes)
    metrics["out_of_fold"] = len(folds) > 1
    metrics["n_segments"] = len(segments)
    metrics["labelled_samples"] = int(sum(s[2] - s[1] for s in segments))
    return ClassifierFit(models, metrics, histories, [v.tolist() for _, v in folds])
