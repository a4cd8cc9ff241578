"""Stage 1 under ``torchrun --nproc-per-node 2`` on CPU (gloo), through the real CLI: the loss curve is the one a
single process draws with the same global batch and seed, never killed, though the two-process run was killed
mid-epoch and went on from its checkpoint."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sessions import Session
from tests.browser.conftest import free_port
from tests.conftest import new_session
from training import load_bundle
from workbench.cli import main

EPOCHS = 3
ROOT = Path(__file__).resolve().parents[2]
# float sums in another order: DDP adds two half-batch gradients where one process adds them all at once, and Adam
# carries the difference from epoch to epoch (measured over 3 epochs: 7e-9 to 7e-8 relative)
REL = 1e-5


@pytest.fixture(scope="module")
def logs_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from workbench.demo import generate_demo_logs

    tmp = tmp_path_factory.mktemp("ddp")
    logs = generate_demo_logs(tmp / "logs", n_logs=3, minutes=1.0, seed=8)
    with new_session(tmp / "s") as s:
        s.ingest(logs)
    return tmp / "s"


def copy_of(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def run(args: list[str], *, procs: int = 1, script: str | None = None, world: int = 1) -> subprocess.CompletedProcess:
    """The CLI in ``procs`` processes under torchrun, or in one (told ``WORLD_SIZE=world`` as torchrun would)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    if world > 1:
        env.update(WORLD_SIZE=str(world), RANK="0", LOCAL_RANK="0")
    if procs == 1:
        cmd = [sys.executable, "-m", "workbench.cli", *args]
    else:
        launcher = [
            sys.executable,
            "-m",
            "torch.distributed.run",
            f"--nproc-per-node={procs}",
            "--master-addr=127.0.0.1",
            f"--master-port={free_port()}",
        ]
        cmd = [*launcher, script] if script else [*launcher, "-m", "workbench.cli"]
        cmd += args
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


def train_args(session: Path) -> list[str]:
    return [
        "train",
        str(session),
        "--stage",
        "predictor",
        "--model",
        "paper",
        "--hidden",
        "8",
        "--batch-size",
        "4",
        "--max-epochs",
        str(EPOCHS),
        "--patience",
        str(EPOCHS),
    ]


def history(session: Path) -> list[dict[str, float]]:
    with Session.open(session) as s:
        (v,) = s.model_versions("predictor")
        return load_bundle(s.path / v.path).info["history"]


def test_two_processes_killed_mid_epoch_resume_and_draw_the_loss_curve_of_one(
    logs_session: Path, tmp_path: Path
) -> None:
    """Two facts, one two-process training (a torchrun launch is three interpreters): killed half-way through epoch
    2, it leaves a checkpoint and no version; run again it goes on from there, and the curve it ends with is the one
    a single process draws never killed. A resume that repeated or skipped a batch would be far off that curve."""
    # the single process's curve, trained in this one (no launch: an interpreter fewer, the same CLI)
    assert main(train_args(copy_of(logs_session, tmp_path / "one"))) == 0
    two = copy_of(logs_session, tmp_path / "two")
    dead = run([str(two), str(EPOCHS)], procs=2, script="tests/workbench/ddp_kill_worker.py")
    assert dead.returncode != 0, "the main process was to kill itself"
    with Session.open(two) as s:
        assert s.model_versions("predictor") == []  # nothing half-done is listed
    assert list((two / "cache" / "checkpoints").glob("predictor-*.safetensors"))
    again = run(train_args(two), procs=2)
    assert again.returncode == 0, again.stderr
    assert "predictor: resuming from the checkpoint at epoch 2, batch " in again.stderr, again.stderr
    assert again.stdout.count("predictor v1:") == 1, again.stdout  # the main process reports, once
    h1, h2 = history(tmp_path / "one"), history(two)
    assert len(h1) == len(h2) == EPOCHS
    for a, b in zip(h1, h2, strict=True):
        assert b["train_loss"] == pytest.approx(a["train_loss"], rel=REL)
        assert b["val_loss"] == pytest.approx(a["val_loss"], rel=REL)
    with Session.open(two) as s:
        (v,) = s.model_versions("predictor")
        assert v.active and load_bundle(s.path / v.path).info["processes"] == 2
        assert not list((s.path / "cache" / "checkpoints").glob("predictor*.safetensors"))  # gone once saved


def test_only_the_predictor_trains_under_torchrun(
    logs_session: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    # both refusals come before any process group is joined, so the CLI in this process, told the WORLD_SIZE
    # torchrun sets (`distributed.launched`), shows each without a launch or an interpreter of its own
    from workbench.cli import main

    for key, value in {"WORLD_SIZE": "2", "RANK": "0", "LOCAL_RANK": "0"}.items():
        monkeypatch.setenv(key, value)
    assert main(["train", str(copy_of(logs_session, tmp_path / "s")), "--stage", "classifier"]) == 2
    err = capsys.readouterr().err
    assert err.count("error: under torchrun only the predictor trains (--stage predictor)") == 1
    assert "Traceback" not in err
    # the default family's stage 1 trains in one process, in seconds
    assert main(["train", str(copy_of(logs_session, tmp_path / "d")), "--stage", "predictor"]) == 2
    err = capsys.readouterr().err
    assert err.count("error: under torchrun only the paper family's LSTM predictor trains") == 1
    assert "Traceback" not in err
