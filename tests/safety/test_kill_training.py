"""Promise 2: training can die at any moment. Killed mid-epoch or mid-save, the session opens, the previous active
model still loads and scores, and no half-written version is listed."""

from __future__ import annotations

import signal
import textwrap
from pathlib import Path

import numpy as np
import pytest

from sessions import Session
from tests.fork_client import ForkServer
from training import TrainConfig
from training.runtime.bundle import load_bundle
from workbench import cycle
from workbench.cycle import score_session

# A training run in its own process, killed by SIGKILL from inside at a chosen point: after N optimiser steps
# (mid-epoch), while a weights file is half written (mid-save), or with the files in place but not yet registered.
CHILD = textwrap.dedent(
    """
    import os, signal, sys
    from sessions import Session
    from training import TrainConfig
    from workbench import cycle
    import training.runtime.bundle as bundle

    path, where, stage, steps = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])

    def die():
        os.kill(os.getpid(), signal.SIGKILL)

    count = [0]

    def progress(p):
        count[0] += 1
        if where == "epoch" and count[0] >= steps:
            die()

    if where == "save":
        real = bundle.save_file

        def half(tensors, filename, **kw):
            real(tensors, filename, **kw)
            with open(filename, "r+b") as f:
                f.truncate(os.path.getsize(filename) // 2)
            die()

        bundle.save_file = half
    if where == "register":
        Session.register_model = lambda *a, **k: die()
    if where == "epoch":  # start afresh, so the kill comes at the step asked for (resuming: test_checkpoint.py)
        import glob
        for ckpt in glob.glob(os.path.join(path, "cache", "checkpoints", "predictor*.safetensors")):
            os.remove(ckpt)
    config = TrainConfig(max_epochs=3, patience=2, chunk=32, piece=256, batch_size=16, label_piece=64, context=32,
                         k_folds=3)
    with Session.open(path) as s:
        train = cycle.train_predictor if stage == "predictor" else cycle.train_classifier
        train(s, config=config, hidden=8, progress=progress)
    sys.exit(3)  # not killed: the test's hook never fired
    """
)


TRAINING_MODULES = ("torch", "sessions", "training", "workbench.cycle")  # imported once by the server, not per kill


def kill_training(path: Path, where: str, stage: str, steps: int = 1) -> None:
    """``CHILD`` in a process of its own (forked from one that imported PyTorch once: ``tests/fork_server.py``)."""
    ran = ForkServer.run(TRAINING_MODULES, CHILD, [str(path), where, stage, str(steps)], timeout=300)
    assert ran.code == -signal.SIGKILL and not ran.killed, ran.err[-2000:]


def state_of(path: Path) -> tuple:
    with Session.open(path) as s:
        return tuple((v.id, v.stage, v.active, v.path) for v in s.model_versions())


def check_after_kill(path: Path, before: tuple) -> None:
    """Opens; the same versions listed and active as before the kill; each loads; the active ones score."""
    assert state_of(path) == before
    with Session.open(path) as s:
        for v in s.model_versions():
            load_bundle(s.path / v.path)  # every listed version is whole
        scores = score_session(s)
        assert scores and all(np.isfinite(sc.probs).all() for sc in scores.values())


@pytest.fixture(scope="module")
def trained_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tests.workbench.cycle.test_cycle import build_trained
    from workbench.demo import generate_demo_logs

    root = tmp_path_factory.mktemp("killtrain")
    build_trained(root / "s", generate_demo_logs(root / "logs", n_logs=2, minutes=1.0, seed=5)).close()
    return root / "s"


@pytest.mark.parametrize(
    ("where", "stage", "steps"),
    [
        ("epoch", "classifier", 2),
        ("epoch", "predictor", 2),
        ("save", "classifier", 0),
        ("save", "predictor", 0),
        ("register", "classifier", 0),
    ],
)
def test_a_training_killed_anywhere_leaves_the_previous_models_working(
    trained_session: Path, where: str, stage: str, steps: int
) -> None:
    before = state_of(trained_session)
    kill_training(trained_session, where, stage, steps)
    check_after_kill(trained_session, before)


def test_a_predictor_killed_while_saving_is_saved_by_the_next_run_without_training_again(tmp_path: Path) -> None:
    from tests.workbench.cycle.test_cycle import build_trained
    from workbench.demo import generate_demo_logs

    path = tmp_path / "s"
    build_trained(path, generate_demo_logs(tmp_path / "logs", n_logs=2, minutes=0.5, seed=2)).close()
    before = state_of(path)
    kill_training(path, "save", "predictor")
    check_after_kill(path, before)
    resumed: list[tuple[int, int]] = []
    steps: list[object] = []
    with Session.open(path) as s:
        config = TrainConfig(
            max_epochs=3, patience=2, chunk=32, piece=256, batch_size=16, label_piece=64, context=32, k_folds=3
        )  # what CHILD trains with
        v = cycle.train_predictor(
            s, config=config, hidden=8, progress=steps.append, on_resume=lambda e, b: resumed.append((e, b))
        )
        assert v.active and len(s.model_versions("predictor")) == 2
        load_bundle(s.path / v.path)
    assert resumed and resumed[0][1] == 0 and steps == []  # the finished run's checkpoint: nothing left to train


def run_random_kills(path: Path, kills: int, seed: int) -> int:
    """Kills after a random number of optimiser steps, each stage in turn; returns how many were checked."""
    rng = np.random.default_rng(seed)
    for i in range(kills):
        before = state_of(path)
        kill_training(path, "epoch", ("classifier", "predictor")[i % 2], int(rng.integers(1, 12)))
        check_after_kill(path, before)
    return kills


@pytest.mark.slow
def test_training_killed_at_forty_random_moments(trained_session: Path, promise) -> None:
    n = run_random_kills(trained_session, 40, seed=3)
    promise(
        f"promise 2 (training can die at any moment): {n} kills at random steps, 0 failures; every listed "
        "version loaded and the active ones scored after each"
    )
