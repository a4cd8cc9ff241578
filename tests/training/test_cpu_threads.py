"""Threads for the CPUs that are free (issue 53, item 3): the count, its bounds, and what a user set winning."""

from __future__ import annotations

import pytest
import torch

from training import free_cpus, threads_for, usable_cpus, use_free_cpus


@pytest.mark.parametrize(("free", "cpus", "threads"), [(2.0, 2, 2), (1.5, 2, 2), (1.2, 2, 1), (0.1, 2, 1), (7.9, 4, 4)])
def test_threads_follow_the_free_cpus_and_never_drop_below_one(free: float, cpus: int, threads: int) -> None:
    assert threads_for(free, cpus) == threads


def test_free_cpus_are_between_none_and_those_this_process_may_use() -> None:
    free = free_cpus(sample_s=0.05)
    assert 0.0 <= free <= usable_cpus()


def test_a_thread_count_the_user_set_wins(monkeypatch: pytest.MonkeyPatch) -> None:
    before = torch.get_num_threads()
    monkeypatch.setenv("WORKBENCH_THREADS", "1")
    try:
        assert use_free_cpus(sample_s=0.01) == 1 and torch.get_num_threads() == 1
    finally:
        torch.set_num_threads(before)
