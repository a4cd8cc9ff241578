"""Resumable stage-1 training in one process: the checkpoint file, and a run stopped mid-epoch that goes on from it
to the very result of a run never stopped. Lazy row sources train the same model as arrays in memory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from training import Cancelled, TrainConfig, fit_predictor
from training.running.checkpoint import Checkpoint, fingerprint, load_checkpoint, save_checkpoint

from .test_models import sine_logs

# 8 logs x 4 pieces of 64 = 32 pieces; 26 train -> 7 batches of 4 per epoch
SMALL = TrainConfig(max_epochs=4, patience=4, chunk=16, piece=64, batch_size=4)


def test_a_checkpoint_round_trips_and_refuses_another_run(tmp_path: Path) -> None:
    model = torch.nn.Linear(3, 2)
    opt = torch.optim.Adam(model.parameters())
    model(torch.randn(4, 3)).sum().backward()
    opt.step()
    rng = np.random.default_rng(1)
    rng.random(3)
    ckpt = Checkpoint(
        "abc",
        3,
        2,
        False,
        1.5,
        10.0,
        [{"epoch": 1, "train_loss": 2.0, "val_loss": float("inf")}],
        0.5,
        2,
        1,
        rng.bit_generator.state,
        torch.arange(5),
        model.state_dict(),
        {k: v * 2 for k, v in model.state_dict().items()},
        opt.state_dict(),
    )
    path = tmp_path / "c" / "ckpt.safetensors"
    save_checkpoint(ckpt, path)
    back = load_checkpoint(path, "abc")
    assert back is not None
    assert (back.epoch, back.batch, back.done, back.total, back.count) == (3, 2, False, 1.5, 10.0)
    assert back.history == ckpt.history and back.best == 0.5 and (back.best_epoch, back.since) == (2, 1)
    torch.testing.assert_close(back.order, torch.arange(5))
    for k, v in model.state_dict().items():
        torch.testing.assert_close(back.model[k], v)
        torch.testing.assert_close(back.best_model[k], v * 2)
    opt2 = torch.optim.Adam(torch.nn.Linear(3, 2).parameters())
    opt2.load_state_dict(back.optimizer)  # Adam's moments and step counts come back as Adam wants them
    for a, b in zip(opt.state_dict()["state"].values(), opt2.state_dict()["state"].values(), strict=True):
        torch.testing.assert_close(a["exp_avg_sq"], b["exp_avg_sq"])
        assert float(a["step"]) == float(b["step"])
    restored = np.random.default_rng(0)
    restored.bit_generator.state = back.rng
    assert restored.random() == rng.random()
    assert load_checkpoint(path, "another run") is None
    assert load_checkpoint(tmp_path / "none.safetensors", "abc") is None
    (tmp_path / "junk.safetensors").write_bytes(b"\x10\x00\x00\x00\x00\x00\x00\x00{not json")
    assert load_checkpoint(tmp_path / "junk.safetensors", "abc") is None
    assert not list(path.parent.glob(".*.tmp"))
    assert fingerprint(a=1, b=[1, 2]) == fingerprint(b=[1, 2], a=1) != fingerprint(a=2, b=[1, 2])


def stop_after(steps: int):
    """A cancel callback that stops training after ``steps`` optimiser batches, as a kill would."""
    seen = [0]

    def cancel() -> bool:
        seen[0] += 1
        return seen[0] > steps

    return cancel


@pytest.mark.parametrize("stop", [10, 14], ids=["mid-epoch", "at-an-epoch-end"])
def test_a_stopped_fit_goes_on_from_its_checkpoint_to_the_uninterrupted_result(tmp_path: Path, stop: int) -> None:
    logs = sine_logs(8, 256)
    whole = fit_predictor(logs, config=SMALL, hidden=8)
    path = tmp_path / "predictor.safetensors"
    with pytest.raises(Cancelled):
        fit_predictor(logs, config=SMALL, hidden=8, checkpoint=path, checkpoint_every=3, cancel=stop_after(stop))
    heard: list[tuple[int, int]] = []
    again = fit_predictor(
        logs, config=SMALL, hidden=8, checkpoint=path, checkpoint_every=3, on_resume=lambda e, b: heard.append((e, b))
    )
    # 7 batches an epoch, a checkpoint every 3 and at each epoch's end: stopped in batch 11 (the 4th of epoch 2)
    # -> (epoch 2, batch 3); stopped in batch 15 (the first of epoch 3) -> the end of epoch 2, i.e. (epoch 3, batch 0)
    assert heard == ([(2, 3)] if stop == 10 else [(3, 0)])
    assert again.resumed_from == heard[0]
    assert [h["epoch"] for h in again.history] == [1, 2, 3, 4]
    for a, b in zip(whole.history, again.history, strict=True):
        assert a["train_loss"] == pytest.approx(b["train_loss"], rel=1e-6)
        assert a["val_loss"] == pytest.approx(b["val_loss"], rel=1e-6)
    for k, v in whole.model.state_dict().items():
        torch.testing.assert_close(again.model.state_dict()[k], v, rtol=1e-6, atol=1e-7)


def test_another_configuration_keeps_its_own_checkpoint_and_is_told_of_the_other(tmp_path: Path) -> None:
    """A checkpoint of other settings was silently discarded: the new run restarted at epoch 1 over it."""
    logs = sine_logs(8, 256)
    path = tmp_path / "predictor.safetensors"
    first = fit_predictor(logs, config=SMALL, hidden=8, checkpoint=path)
    assert first.checkpoint is not None and first.checkpoint.exists() and first.checkpoint != path
    assert load_checkpoint(first.checkpoint, "x") is None
    heard: list[tuple[int, int]] = []
    told: list[str] = []
    other = fit_predictor(
        logs,
        config=TrainConfig(**{**SMALL.__dict__, "lr": 0.01}),
        hidden=8,
        checkpoint=path,
        on_resume=lambda e, b: heard.append((e, b)),
        on_other=told.append,
    )
    assert heard == [] and other.resumed_from is None and len(other.history) == 4
    assert len(told) == 1 and "lr 0.005 (now 0.01)" in told[0] and "epoch" in told[0], told
    assert first.checkpoint.exists() and other.checkpoint.exists()  # neither replaced the other
    again: list[tuple[int, int]] = []
    fit_predictor(logs, config=SMALL, hidden=8, checkpoint=path, on_resume=lambda e, b: again.append((e, b)))
    assert again, "the first settings still resume from their own checkpoint"


def test_memory_mapped_logs_train_the_same_model_as_arrays(tmp_path: Path) -> None:
    logs = sine_logs(4, 300)
    rows = []
    for i, a in enumerate(logs):
        np.save(tmp_path / f"{i}.npy", a)
        rows.append(np.load(tmp_path / f"{i}.npy", mmap_mode="r"))  # only each batch's rows are read
    a = fit_predictor(logs, config=SMALL, hidden=8)
    b = fit_predictor(rows, config=SMALL, hidden=8)
    np.testing.assert_array_equal(a.normalizer.mean, b.normalizer.mean)
    assert a.history == b.history
