"""Independent fits side by side, one thread each, on the cores torch would otherwise share within one fit.

A fold's small network gains little from torch's threads (two threads: 1.2 times one, on a 2-core machine; each op
is too small to split well), while two fits in two threads each running torch on one take 1.85 times less time than
one after the other: torch releases the GIL inside its ops. The fits must not share a random generator (each passes
its own) and must build their initial weights under :data:`INIT_LOCK`, so that the results do not depend on how the
threads interleave.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_EXCEPTION, Future, ThreadPoolExecutor, wait
from typing import TypeVar

import torch

T = TypeVar("T")

INIT_LOCK = threading.Lock()  # held while a fit seeds torch's global generator and builds its initial weights


def fit_workers(jobs: int) -> int:
    """Threads for ``jobs`` independent fits: as many as torch's intra-op threads (the cores it was given)."""
    return max(1, min(jobs, torch.get_num_threads()))


def run_fits(jobs: Sequence[Callable[[], T]], *, workers: int, done: Callable[[int], None] | None = None) -> list[T]:
    """Run ``jobs`` and return their results in the jobs' order.

    Args:
        jobs: Independent fits (each draws from its own generator, see the module's note).
        workers: Threads; with one, the jobs run in turn on the calling thread with torch's threads as they are.
            With more, each thread runs torch on one thread for the duration, and the count is restored after.
        done: Called on the calling thread with the number of jobs finished so far, after each one.

    Returns:
        Each job's result.

    Raises:
        Exception: The first job's exception; the jobs not yet started are dropped and the running ones are waited
            for (they poll the same cancel flag, so a cancel stops all of them).
    """
    if workers <= 1 or len(jobs) <= 1:
        out = []
        for i, job in enumerate(jobs):
            out.append(job())
            if done:
                done(i + 1)
        return out
    threads = torch.get_num_threads()

    def one(job: Callable[[], T]) -> T:
        torch.set_num_threads(1)  # per calling thread under OpenMP: each worker sets its own
        return job()

    results: list[T | None] = [None] * len(jobs)
    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="fit")
    try:
        index: dict[Future[T], int] = {pool.submit(one, job): i for i, job in enumerate(jobs)}
        pending = set(index)
        finished = 0
        while pending:
            ready, pending = wait(pending, return_when=FIRST_EXCEPTION)
            for future in ready:
                results[index[future]] = future.result()  # raises the job's exception
                finished += 1
                if done:
                    done(finished)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        torch.set_num_threads(threads)
    return results  # type: ignore[return-value]
