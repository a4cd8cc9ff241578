"""Stage 2's fits in forked processes: results in order, errors as raised, a dead child named, a cancel honoured."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest
import torch

from tests.conftest import children_of_a_killed_parent, ended_within
from training.running import Cancelled, fit_processes, run_fits
from training.running.fit_processes import FitProcessError, fork_safe, forking

pytestmark = pytest.mark.skipif(not forking(), reason="fits fork only on Linux")


@pytest.fixture(autouse=True)
def _forks(request: pytest.FixtureRequest) -> None:
    if "without_forking" not in request.node.name and not fork_safe():
        pytest.skip("this process's autograd has started GPU threads (a CUDA torch with a GPU): fits use threads")


PLAIN = (lambda r: r, lambda r: r)


def _pid_and_square(i: int) -> tuple[int, int, int]:
    return os.getpid(), i * i, torch.get_num_threads()


def test_results_come_back_in_order_from_other_processes_and_progress_on_the_calling_thread() -> None:
    jobs = [lambda i=i: _pid_and_square(i) for i in range(5)]
    seen: list[tuple[int, str]] = []
    threads = torch.get_num_threads()
    out = run_fits(
        jobs,
        workers=2,
        portable=PLAIN,
        done=lambda n: seen.append((n, threading.current_thread().name)),
    )
    assert [square for _, square, _ in out] == [0, 1, 4, 9, 16]
    assert os.getpid() not in {pid for pid, _, _ in out}  # each ran in a child
    assert {t for _, _, t in out} == {1}  # one torch thread in each child
    assert seen == [(n, threading.current_thread().name) for n in range(1, 6)]
    assert torch.get_num_threads() == threads


def test_pack_and_unpack_carry_a_result_that_is_not_plain_data() -> None:
    def job() -> torch.nn.Linear:
        torch.manual_seed(3)
        return torch.nn.Linear(4, 2)

    def pack(m: torch.nn.Linear) -> dict[str, np.ndarray]:
        return {k: v.detach().numpy() for k, v in m.state_dict().items()}

    def unpack(state: dict[str, np.ndarray]) -> torch.nn.Linear:
        m = torch.nn.Linear(4, 2)
        m.load_state_dict({k: torch.from_numpy(v) for k, v in state.items()})
        return m

    a, b = run_fits([job, job], workers=2, portable=(pack, unpack))
    assert torch.equal(a.weight, job().weight) and torch.equal(b.bias, job().bias)


def test_a_fit_that_raises_raises_the_same_error_in_the_caller() -> None:
    def bad() -> int:
        raise ValueError("the labelled segments are shorter than one frame")

    with pytest.raises(ValueError, match="shorter than one frame"):
        run_fits([lambda: 1, bad, lambda: 3], workers=2, portable=PLAIN)


def test_a_child_that_dies_is_named_not_waited_for() -> None:
    def dies() -> int:
        os._exit(9)  # as the kernel's out-of-memory killer would end it

    with pytest.raises(FitProcessError, match=r"fit 2 of 2 ended without a result \(exit code 9"):
        run_fits([lambda: 1, dies], workers=2, portable=PLAIN)


def test_a_cancel_ends_the_children() -> None:
    t = time.monotonic()
    with pytest.raises(Cancelled):
        run_fits([lambda: time.sleep(30)] * 3, workers=2, portable=PLAIN, cancel=lambda: time.monotonic() - t > 0.5)
    assert time.monotonic() - t < 10


def test_without_forking_the_fits_run_in_threads_of_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("WORKBENCH_FIT_PROCESSES", "0")
    out = run_fits([lambda i=i: _pid_and_square(i) for i in range(3)], workers=2, portable=PLAIN)
    assert {pid for pid, _, _ in out} == {os.getpid()} and [s for _, s, _ in out] == [0, 1, 4]


def test_a_torch_that_refuses_forked_fits_falls_back_to_threads_for_good(monkeypatch: pytest.MonkeyPatch) -> None:
    """As a CUDA torch does once its autograd has started GPU threads: a RuntimeError in every child."""
    monkeypatch.setattr(fit_processes, "_UNSAFE", [])
    parent = os.getpid()

    def fit(i: int) -> tuple[int, int, int]:
        if os.getpid() != parent:
            raise RuntimeError("Unable to handle autograd's threading in combination with fork-based multiprocessing")
        return _pid_and_square(i)

    with pytest.warns(UserWarning, match="run in threads from now on"):
        out = run_fits([lambda i=i: fit(i) for i in range(3)], workers=2, portable=PLAIN)
    assert [s for _, s, _ in out] == [0, 1, 4] and {pid for pid, _, _ in out} == {parent}
    assert not fork_safe()  # and no later fit is forked
    again = run_fits([lambda: _pid_and_square(2)] * 2, workers=2, portable=PLAIN)
    assert {pid for pid, _, _ in again} == {parent}


def test_hiding_the_gpus_leaves_a_chosen_device_list_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "0")
    assert not fit_processes.hide_gpus() and os.environ["CUDA_VISIBLE_DEVICES"] == "0"
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES")
    if not torch.cuda.is_initialized():  # a CPU run on a machine whose GPUs torch has not counted yet
        assert fit_processes.hide_gpus() and os.environ["CUDA_VISIBLE_DEVICES"] == ""


def test_a_killed_parent_leaves_no_fit_running(tmp_path) -> None:
    """A `train` killed with SIGKILL (as the kill tests do) takes its forked fits with it."""

    pids = tmp_path / "pids"

    def fit() -> None:
        with pids.open("a") as f:
            f.write(f"{os.getpid()}\n")
        time.sleep(60)

    # a process standing for `train`, forked from this one (torch already imported)
    children = children_of_a_killed_parent(lambda: run_fits([fit, fit], workers=2, portable=PLAIN), pids, 2)
    assert ended_within(children, 10)
