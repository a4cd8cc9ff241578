"""One thread runs the server's PyTorch work: the Retrain, the scoring, the export.

PyTorch on this CPU build parallelises through libgomp, which gives every thread that enters a parallel region its
own team of worker threads. Once two such threads are alive the process manages more OpenMP threads than there are
cores, and libgomp then stops spinning between parallel regions and sleeps on a futex instead; an LSTM runs a few
small parallel regions per time step, so every step pays for waking the team. Measured on 2 cores (a 2-layer LSTM
over 20,000 steps, ``benchmarks/speed/bench_torch_lane.py``): 0.07 s on the thread that ran torch first, 1.2 s on a
second thread while the first is alive. The UI ran its Retrain, its scoring and viser's callbacks on different
threads, so it paid that on every pass.

The cause is several threads running torch, so the fix is one: ``workbench serve`` gives its main thread to
:data:`LANE` (it only slept before), and the job thread, the scoring worker and the page's callbacks hand their
torch work to it and wait. Work from the lane's own thread, or from a process that serves no lane (the CLI, the
tests), runs where it is called, as before.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

from sessions import WorkbenchError

T = TypeVar("T")
EXPECT_WAIT_S = 60.0  # a server's start-up (viser, the gate) takes seconds; past this, calls run where they are


class TorchLane:
    """A queue of calls run one after another by the thread that serves it."""

    def __init__(self) -> None:
        self._tasks: queue.SimpleQueue[tuple[Callable[..., Any], tuple, dict, Future]] = queue.SimpleQueue()
        self._owner: threading.Thread | None = None
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        self._expected = False  # a thread is about to serve: calls wait for it rather than run where they are

    @property
    def serving(self) -> bool:
        """A thread serves the lane now."""
        return self._owner is not None

    def expect(self) -> None:
        """Say that a thread will serve the lane shortly: until it does, calls wait for it (at most
        ``EXPECT_WAIT_S``) instead of running torch in their own threads, whose thread pools would then stay alive
        beside the lane's."""
        with self._lock:
            self._expected = True

    def expect_no_more(self) -> None:
        """Nobody will serve after all (the server did not start): calls run where they are made again."""
        with self._lock:
            self._expected = False
            self._changed.notify_all()

    def run(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
        """``fn(*args, **kwargs)`` on the lane's thread, waiting for it; where called when no thread serves it.

        Exceptions raised by ``fn`` are raised here, in the caller's thread.
        """
        with self._lock:
            if self._owner is None and self._expected:
                self._changed.wait_for(lambda: self._owner is not None or not self._expected, EXPECT_WAIT_S)
            owner = self._owner
            if owner is None or owner is threading.current_thread():
                done = None
            else:
                done = Future()
                self._tasks.put((fn, args, kwargs, done))
        if done is None:
            return fn(*args, **kwargs)
        return done.result()

    def serve(
        self, stop: Callable[[], bool], *, poll_s: float = 0.25, started: Callable[[], None] | None = None
    ) -> None:
        """Run the lane's calls in this thread until ``stop()`` is true (or Ctrl+C); calls left then fail.

        ``started`` is called once the lane is served (work it starts is then sure to come here).
        """
        with self._lock:
            if self._owner is not None:
                raise RuntimeError("the lane is served already")
            self._owner = threading.current_thread()
            self._changed.notify_all()
        try:
            if started is not None:
                started()
            while not stop():
                try:
                    fn, args, kwargs, done = self._tasks.get(timeout=poll_s)
                except queue.Empty:
                    continue
                if not done.set_running_or_notify_cancel():
                    continue
                try:
                    done.set_result(fn(*args, **kwargs))
                except KeyboardInterrupt:  # a second Ctrl+C: the caller hears that the server stops, in one line
                    done.set_exception(WorkbenchError("the server is stopping; nothing was changed"))
                    raise
                except BaseException as exc:
                    done.set_exception(exc)
        finally:
            with self._lock:
                self._owner = None
                self._expected = False
                self._changed.notify_all()
                while True:
                    try:
                        *_, done = self._tasks.get_nowait()
                    except queue.Empty:
                        break
                    if done.set_running_or_notify_cancel():
                        done.set_exception(WorkbenchError("the server is stopping; nothing was changed"))


LANE = TorchLane()  # one per process: libgomp's thread pools are per process
