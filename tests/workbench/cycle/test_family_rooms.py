"""Issue 67: a family is a room and one registry line, also for the cycle. A third family (the logistic regression
on the default family's frames of ``tests/training/third_family.py``) and a fourth written here (a linear model per
step on the paper family's stage-1 outputs) are trained, scored and suggested from by the session's own path,
``cycle.train_stage1`` -> ``cycle.train_classifier`` -> ``cycle.compute_scores`` -> ``cycle.suggest_for_session``,
with no edit outside their rooms: the cycle calls what a family declares (its stage 1, its inputs, its fit) and never
asks which one it is.
"""

from __future__ import annotations

import contextlib
import sys
import types
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn
from torch.nn import functional as F

import training
from sessions import Session, WorkbenchError
from tests.conftest import new_session
from tests.training.third_family import FAMILY as LOGREG
from tests.training.third_family import ROOM as LOGREG_ROOM
from training import ClassifierFit, Family, TrainConfig, classification_metrics, fold_indices, load_bundle, never
from workbench import cycle
from workbench.demo import generate_demo_logs, seed_labels

from .test_cycle import TINY

STEP_KIND, STEP_ROOM = "steplinear", "stage1_linear"


@dataclass(frozen=True)
class StepLinearConfig:
    """One linear layer over a step's stage-1 features."""

    n_features: int
    n_classes: int
    kind: str = STEP_KIND


class StepLinear(nn.Module):
    """Standardise the step's features, then one linear layer; no state."""

    def __init__(self, config: StepLinearConfig) -> None:
        super().__init__()
        self.config = config
        self.register_buffer("in_mean", torch.zeros(config.n_features))
        self.register_buffer("in_scale", torch.ones(config.n_features))
        self.linear = nn.Linear(config.n_features, config.n_classes)

    def forward(self, features: torch.Tensor, state: None = None) -> tuple[torch.Tensor, None]:
        """``features (B, T, F)`` -> ``logits (B, T, K)``."""
        return self.linear((features - self.in_mean) * self.in_scale), None


def fit_step_linear(
    features: Sequence[np.ndarray],
    segments: Sequence[tuple[int, int, int, int]],
    classes: Sequence[str],
    *,
    config: TrainConfig,
    hidden: int = 0,
    init: Sequence[StepLinear] | None = None,
    new: Sequence[int] | None = None,
    pairs: Sequence = (),
    progress=None,
    cancel=never,
) -> ClassifierFit:
    """k fold models on the labelled steps, each from ``init``'s weights when the cycle hands them (a warm start)."""
    rows = [np.array(features[i][a:b], np.float32) for i, a, b, _ in segments]  # (n_i, F) each, writable
    folds = fold_indices([s[3] for s in segments], config.k_folds, config.seed)
    every = np.concatenate(rows)
    mean, std = every.mean(0), np.where(every.std(0) > 1e-8, every.std(0), 1.0)
    models, true, pred = [], [], []
    for f, (train_idx, val_idx) in enumerate(folds):
        torch.manual_seed(config.seed)
        model = StepLinear(StepLinearConfig(every.shape[1], len(classes)))
        if init is not None:
            model.load_state_dict(init[f % len(init)].state_dict())
        else:
            model.in_mean.copy_(torch.from_numpy(mean))
            model.in_scale.copy_(torch.from_numpy(1.0 / std))
        x = torch.from_numpy(np.concatenate([rows[i] for i in train_idx]))
        y = torch.from_numpy(np.concatenate([np.full(len(rows[i]), segments[i][3]) for i in train_idx]))
        opt = torch.optim.Adam(model.parameters(), lr=0.05)
        for _ in range(100):
            opt.zero_grad()
            F.cross_entropy(model(x[None])[0][0], y).backward()
            opt.step()
        models.append(model.eval())
        with torch.inference_mode():
            for i in val_idx:
                true.append(np.full(len(rows[i]), segments[i][3]))
                pred.append(model(torch.from_numpy(rows[i])[None])[0][0].argmax(1).numpy())
    metrics = classification_metrics(np.concatenate(true), np.concatenate(pred), classes)
    return ClassifierFit(models, metrics, [[] for _ in models], [v.tolist() for _, v in folds])


def _no_stream(*args, **kwargs):
    raise NotImplementedError("the test's fourth family is trained and scored in a session; it has no stream")


STEP_LINEAR = Family(
    name="steplinear",
    summary="one linear layer per step on the LSTM predictor's outputs",
    kind=STEP_KIND,
    stage2_inputs="stage1",
    new_classifier=lambda cfg: StepLinear(StepLinearConfig(**cfg)),
    stream_step=_no_stream,
    precisions=("float32",),
    step_module=_no_stream,
    onnx_inputs=("x",),
    onnx_outputs=("probs",),
    stream_axes=(0,),
    zero_state=_no_stream,
    describe=lambda bundle: "Steplinear family: a linear layer per step on stage 1's outputs.",
    onnx_usage=lambda bundle: "",
    fit=fit_step_linear,
    warm_start=True,
    stage1="lstm",
)


@contextlib.contextmanager
def rooms(*families: tuple[str, Family]) -> Iterator[None]:
    """Each family where ``training.family`` imports it from (its room), and its line in ``FAMILY_ROOMS``."""
    with pytest.MonkeyPatch.context() as mp:
        for room, fam in families:
            module = types.ModuleType(f"training.{room}")
            module.FAMILY = fam
            mp.setitem(sys.modules, f"training.{room}", module)
            mp.setitem(training.FAMILY_ROOMS, fam.name, room)
        yield


@pytest.fixture(scope="module")
def session(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Session]:
    root = tmp_path_factory.mktemp("rooms")
    s = new_session(root / "s")
    s.ingest(generate_demo_logs(root / "logs", n_logs=2, minutes=0.5, seed=5))
    seed_labels(s, 0.15, seed=1)
    yield s
    s.close()


def _through_the_cycle(s: Session, name: str) -> tuple[Path, int]:
    """Both stages of family ``name`` as ``workbench train --model NAME`` runs them, then the UI's scores and queue.
    Returns the classifier's bundle folder and how many suggestions came."""
    cycle.train_stage1(s, model=name, config=TINY, hidden=8)
    version = cycle.train_classifier(s, model=name, config=TINY, hidden=8)
    assert version.config["model"] == name and cycle.classifier_family(s) == name
    scores = cycle.compute_scores(s)
    assert scores.classifier == version.id and len(scores.classes) >= 2
    for log in s.logs():
        probs = scores.scores[log.id].probs
        assert probs.shape == (log.n_samples, len(scores.classes)) and np.isfinite(probs).all()
        np.testing.assert_allclose(probs.sum(1), 1.0, atol=1e-5)
    points = {x.id: cycle.signal_change_points(s, x) for x in s.logs()}
    queue = cycle.suggest_for_session(s, scores, points, logs=s.logs(), n=4)
    return s.path / version.path, len(queue)


@pytest.mark.usefixtures("quick_stage1", "fast_window_fits")
def test_a_third_and_a_fourth_family_run_the_cycle_with_no_edit_outside_their_rooms(session: Session) -> None:
    with rooms((LOGREG_ROOM, LOGREG), (STEP_ROOM, STEP_LINEAR)):
        assert {"logreg", "steplinear"} <= set(training.family_names())
        fourth, queued = _through_the_cycle(session, "steplinear")  # stage 1's outputs: the LSTM predictor first
        bundle = load_bundle(fourth)
        assert bundle.family == "steplinear" and bundle.stage1_kind == "lstm" and queued == 4
        assert type(bundle.classifiers[0]) is StepLinear
        # a Retrain follows the active family; the cycle hands the active models to a family that warm-starts
        again = cycle.train_classifier(session, config=TINY, hidden=8, warm_epochs=1)
        assert again.config["model"] == "steplinear" and again.config["warm_start"] is True
        third, queued = _through_the_cycle(session, "logreg")  # the next-frame predictor, then its frames
        assert load_bundle(third).family == "logreg" and queued == 4
        assert load_bundle(session.path / session.active_model("predictor").path).stage1_kind == "next-frame"
        # a family reading stage 1's outputs over another kind of stage 1 is refused in one line, naming the fix
        with pytest.raises(WorkbenchError, match="--model steplinear"):
            cycle.train_classifier(session, model="steplinear", config=TINY, hidden=8)
