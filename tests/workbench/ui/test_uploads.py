"""The server's upload budget on its own: one total for every client, a count per client, stalled uploads give
their room (tests/safety/test_upload_totals.py has it against a served workbench)."""

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
    budget = UploadBudget(max_bytes=300 * MB, max_in_flight=300 * MB, per_client=2, stalled_s=0.05)
    buffers = {"a": {"parts": {0: b"x"}}}
    budget.attach(1, buffers)
    assert budget.reserve("a", 1, "a.mcap", 300 * MB) is None
    assert budget.touch("a")
    assert budget.reserve("b", 2, "b.mcap", 100 * MB) is not None  # a is sending: no room
    time.sleep(0.1)
    assert budget.reserve("b", 2, "b.mcap", 100 * MB) is None  # a sent nothing for 0.05 s: dropped
    assert buffers == {} and not budget.touch("a")  # its parts are gone, and so are its later ones
