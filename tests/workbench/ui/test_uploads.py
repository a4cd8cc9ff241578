"""The server's upload budget on its own: one total for every client, a count per client, uploads under the minimum
rate give their room (tests/safety/test_upload_totals.py has it against a served workbench)."""

from __future__ import annotations

import time

from workbench.ui.uploads import UploadBudget

MB = 1 << 20


def test_the_total_counts_every_client_and_comes_back_when_they_finish_or_leave() -> None:
    budget = UploadBudget(max_bytes=300 * MB, max_in_flight=500 * MB, per_client=2)
    assert budget.reserve("a", 1, "a.mcap", 200 * MB) is None
    assert budget.reserve("b", 2, "b.mcap", 200 * MB) is None
    why = budget.reserve("c", 3, "../c.mcap", 200 * MB)
    assert why is not None and "receiving 400 MB of uploads already" in why and "at most 500 MB" in why
    assert why.startswith("c.mcap:")  # the name as it would be saved, never a path
    assert budget.reserve("big", 3, "big.mcap", 301 * MB) == "big.mcap: 301.0 MB is over the 300 MB upload limit"
    budget.release("a")  # finished
    assert budget.reserve("c", 3, "c.mcap", 200 * MB) is None
    assert budget.in_flight() == 400 * MB
    assert budget.release_client(2) == 1 and budget.release_client(2) == 0  # left
    assert budget.in_flight() == 200 * MB


def test_a_client_sends_at_most_per_client_at_once() -> None:
    budget = UploadBudget(max_bytes=10 * MB, max_in_flight=100 * MB, per_client=2)
    assert budget.reserve("a1", 1, "a1.csv", MB) is None
    assert budget.reserve("a2", 1, "a2.csv", MB) is None
    assert (
        budget.reserve("a3", 1, "a3.csv", MB)
        == "a3.csv: this page is already sending 2 uploads; wait for one to finish"
    )
    assert budget.reserve("b1", 2, "b1.csv", MB) is None  # another page is not held back


def test_a_stalled_upload_gives_its_room_and_its_buffers_to_one_that_needs_them() -> None:
    budget = UploadBudget(max_bytes=300 * MB, max_in_flight=300 * MB, per_client=2, window_s=0.05)
    buffers = {"a": {"parts": {0: b"x"}}}
    budget.attach(1, buffers)
    assert budget.reserve("a", 1, "a.mcap", 300 * MB) is None
    assert budget.touch("a", MB)
    assert budget.reserve("b", 2, "b.mcap", 100 * MB) is not None  # a is sending: no room
    time.sleep(0.1)
    assert budget.reserve("b", 2, "b.mcap", 100 * MB) is None  # a sent nothing for 0.05 s: dropped
    assert buffers == {} and not budget.touch("a", MB)  # its parts are gone, and so are its later ones
    assert budget.dropped_slow == 1


class Clock:
    """A clock the test moves."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_trickle_under_the_minimum_rate_gives_its_room_up() -> None:
    """Issue 64, item 3, on a clock the test moves: 1 MB, then 1 KB every 30 s. Before, a part of any size counted
    as progress, and the trickle held 510 MB of room for ever."""
    clock = Clock()
    budget = UploadBudget(max_bytes=512 * MB, max_in_flight=512 * MB, clock=clock)
    assert (budget.window_s, budget.min_bytes) == (30.0, MB)
    assert budget.reserve("trickle", 1, "t.mcap", 510 * MB) is None
    clock.now = 1.0
    assert budget.touch("trickle", MB)  # it met the rate at 1 s
    clock.now = 5.0
    assert "receiving 510 MB" in str(budget.reserve("b", 2, "b.mcap", 10 * MB))  # +5 s: the trickle keeps its room
    for clock.now in (30.0, 60.0):
        assert budget.touch("trickle", 1024)
    clock.now = 70.0  # 2 KB in the 69 s since its megabyte: under the rate, its room goes to the upload that needs it
    assert budget.reserve("b", 2, "b.mcap", 10 * MB) is None
    assert not budget.touch("trickle", 1024) and budget.dropped_slow == 1


def test_an_upload_at_the_rate_keeps_its_room_and_its_last_bytes_may_be_few() -> None:
    clock = Clock()
    budget = UploadBudget(max_bytes=512 * MB, max_in_flight=512 * MB, clock=clock)
    assert budget.reserve("a", 1, "a.mcap", 3 * MB + 10) is None
    for clock.now in (29.0, 58.0, 87.0):  # a megabyte every 29 s: just above the rate
        assert budget.touch("a", MB)
    clock.now = 116.0
    assert budget.touch("a", 10)  # the last 10 bytes meet the rate: they are the rest of the file
    clock.now = 140.0
    assert budget.reserve("b", 2, "b.mcap", 509 * MB) is not None and budget.dropped_slow == 0
