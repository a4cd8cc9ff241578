"""The default family's quick fine-tune: folds carried over, fold models that learn nothing new left as they were,
honest out-of-fold figures, and a fine-tune that learns from the new labels."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from training import (
    Normalizer,
    SpectralConfig,
    SpectralSteps,
    WindowFitConfig,
    assign_folds,
    fine_tune_window_classifier,
    fit_window_classifier,
    log_frames,
)

from .test_window_family import RATE, _walk

CLASSES = ("a", "b", "c")


def test_known_folds_are_kept_and_new_segments_join_the_fold_with_fewest_of_their_terrain() -> None:
    labels = [0, 0, 1, 1, 0, 1, 0, 2]
    known = [0, 1, 0, 2, -1, -1, -1, -1]
    folds = assign_folds(labels, known, 3)
    assert folds[:4] == [0, 1, 0, 2]
    assert folds[4] == 2  # terrain 0 sits in folds 0 and 1
    assert folds[5] == 1  # terrain 1 in 0 and 2
    assert folds[6] == 0  # terrain 0 once in each fold, and two segments in each: the lowest
    assert folds[7] == 1  # a terrain seen nowhere: the folds hold 3, 2, 2 segments
    assert assign_folds([2], [-1], 3) == [0]
    assert assign_folds([0, 0, 0], [5, -1, -1], 2) == [0, 1, 0]  # an index out of range is unknown


@pytest.fixture(scope="module")
def setting():
    rng = np.random.default_rng(3)
    terrains = [0, 1, 2] * 4
    arrays = [_walk(2400, k, rng) for k in terrains]
    normalizer = Normalizer.fit(arrays)
    config = SpectralConfig.for_log(arrays[0], RATE)
    feats = [SpectralSteps(log_frames(a, config, transform=normalizer), len(a), config) for a in arrays]
    return feats, terrains


def _accuracy(models, feats, terrains, logs) -> float:
    hits = total = 0
    with torch.inference_mode():
        for i in logs:
            x = torch.from_numpy(feats[i][1200:2400])[None]  # (1, L, D) unlabelled half
            probs = torch.stack([m(x)[0][0].softmax(-1) for m in models]).mean(0)
            hits += int((probs.argmax(1).numpy() == terrains[i]).sum())
            total += 1200
    return hits / total


def test_a_fine_tune_learns_the_new_labels_and_keeps_folds_out_of_fold(setting) -> None:
    feats, terrains = setting
    old = [(i, 0, 1200, k) for i, k in enumerate(terrains[:3])]  # one log of each terrain
    weak = WindowFitConfig(k_folds=3, epochs=1, max_steps=2, lr=1e-6, self_training=False, held_out=False)
    first = fit_window_classifier(feats, old, CLASSES, config=weak)  # next to untrained
    known = [-1] * len(old)
    for f, val in enumerate(first.folds):
        for i in val:
            known[i] = f
    segments = old + [(i, 0, 1200, terrains[i]) for i in range(3, 9)]
    folds = assign_folds([s[3] for s in segments], known + [-1] * 6, 3)
    assert folds[:3] == known
    new = list(range(3, 9))
    tuned = fine_tune_window_classifier(
        feats, segments, CLASSES, first.models, folds=folds, new=new, steps=120, lr_scale=1.0, config=WindowFitConfig()
    )
    unseen = range(9, 12)
    before, after = _accuracy(first.models, feats, terrains, unseen), _accuracy(tuned.models, feats, terrains, unseen)
    assert after > 0.9 and after > before + 0.2, (before, after)
    # out-of-fold: every labelled step once, each by the fold model that never trained on its segment
    assert tuned.metrics["n"] == sum(b - a for _, a, b, _ in segments) and tuned.metrics["out_of_fold"]
    assert sorted(i for val in tuned.folds for i in val) == list(range(len(segments)))
    assert all(folds[i] == f for f, val in enumerate(tuned.folds) for i in val)
    # the standardisation of the models fine-tuned is theirs, unchanged
    for a, b in zip(first.models, tuned.models, strict=True):
        assert torch.equal(a.in_mean, b.in_mean) and torch.equal(a.in_scale, b.in_scale)


def test_a_fold_model_with_nothing_new_outside_its_fold_is_left_as_it_was(setting) -> None:
    feats, terrains = setting
    old = [(i, 0, 1200, k) for i, k in enumerate(terrains[:6])]
    cfg = WindowFitConfig(k_folds=3, epochs=2, self_training=False, held_out=False)
    first = fit_window_classifier(feats, old, CLASSES, config=cfg)
    known = [next(f for f, val in enumerate(first.folds) if i in val) for i in range(len(old))]
    segments = [*old, (6, 0, 1200, terrains[6])]
    tuned = fine_tune_window_classifier(
        feats, segments, CLASSES, first.models, folds=[*known, 0], new=[6], steps=10, lr_scale=0.3, config=cfg
    )
    same = [
        all(torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters(), strict=True))
        for a, b in zip(first.models, tuned.models, strict=True)
    ]
    assert same == [True, False, False]  # the new segment is fold 0's: model 0 must not see it
    assert tuned.metrics["new_segments"] == 1
    with pytest.raises(ValueError, match="every segment needs a fold"):
        fine_tune_window_classifier(
            feats, segments, CLASSES, first.models, folds=[*known, 3], new=[6], steps=1, lr_scale=1.0, config=cfg
        )
