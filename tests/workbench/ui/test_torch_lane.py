"""The lane that runs the server's torch work on one thread: where calls run, what they return and raise, and what
happens to calls left when it stops. (Its speed is a benchmark: ``benchmarks/speed/bench_torch_lane.py``.)"""

from __future__ import annotations

import threading
import time

import pytest

from sessions import WorkbenchError
from workbench.ui import TorchLane


def test_calls_run_where_they_are_made_when_nothing_serves() -> None:
    lane = TorchLane()
    assert lane.run(threading.current_thread) is threading.current_thread()
    with pytest.raises(ZeroDivisionError):
        lane.run(lambda: 1 / 0)


def test_calls_from_other_threads_run_on_the_serving_thread_one_at_a_time() -> None:
    lane = TorchLane()
    stop = threading.Event()
    results: list[tuple[str, object]] = []
    running = [0, 0]  # now, most at once

    def work(i: int) -> str:
        running[0] += 1
        running[1] = max(running)
        time.sleep(0.01)
        running[0] -= 1
        return f"{i} on {threading.current_thread().name}"

    def caller(i: int) -> None:
        results.append(("ok", lane.run(work, i)))
        try:
            lane.run(lambda: [][1])
        except IndexError as exc:  # raised in the caller's thread
            results.append(("raised", type(exc).__name__))

    callers = [threading.Thread(target=caller, args=(i,)) for i in range(4)]
    launcher = threading.Thread(target=lambda: ([t.start() for t in callers], [t.join() for t in callers], stop.set()))
    name = threading.current_thread().name
    threading.current_thread().name = "lane-owner"
    try:
        lane.serve(stop=stop.is_set, poll_s=0.02, started=launcher.start)  # callers start once it is served
    finally:
        threading.current_thread().name = name
    assert sorted(r for k, r in results if k == "ok") == [f"{i} on lane-owner" for i in range(4)]
    assert [r for k, r in results if k == "raised"] == ["IndexError"] * 4
    assert running[1] == 1 and not lane.serving


def test_an_expected_lane_is_waited_for_and_calls_left_at_stop_fail() -> None:
    lane = TorchLane()
    lane.expect()
    where: list[str] = []
    early = threading.Thread(target=lambda: where.append(lane.run(lambda: threading.current_thread().name)))
    early.start()  # before anything serves: it waits instead of running in its own thread
    time.sleep(0.1)
    assert not where
    outcome: list[str] = []

    def late() -> None:
        try:
            lane.run(lambda: "ran")
            outcome.append("ran")
        except WorkbenchError as exc:
            outcome.append(str(exc))

    t = threading.Thread(target=late)

    def stop() -> bool:
        if not where:
            return False
        t.start()  # a call that arrives while the lane is stopping: queued, never run
        while lane._tasks.empty():
            time.sleep(0.01)
        return True

    name = threading.current_thread().name
    threading.current_thread().name = "lane-thread"
    try:
        lane.serve(stop=stop, poll_s=0.02)
    finally:
        threading.current_thread().name = name
    early.join()
    t.join()
    assert where == ["lane-thread"]
    assert outcome == ["the server is stopping; nothing was changed"]
    assert lane.run(lambda: "inline") == "inline"  # served no more: calls run where they are made


def test_a_server_that_did_not_start_leaves_calls_running_where_they_are_made() -> None:
    lane = TorchLane()
    lane.expect()
    lane.expect_no_more()  # e.g. its port was taken
    started = time.monotonic()
    assert lane.run(threading.current_thread) is threading.current_thread()
    assert time.monotonic() - started < 1.0  # no wait for a lane nobody will serve
