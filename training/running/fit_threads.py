"""Independent fits side by side, one thread (or forked process, :mod:`.fit_processes`) each, on the cores torch
would otherwise share within one fit.

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
from typing import Any, TypeVar

import torch

from .fit_processes import fork_safe, give_up_forking, run_forked
from .progress import CancelFn, never

T = TypeVar("T")

INIT_LOCK = threading.Lock()  # held while a fit seeds torch's global generator and builds its initial weights


def fit_workers(jobs: int) -> int:
    """Threads for ``jobs`` independent fits: as many as torch's intra-op threads (the cores it was given)."""
    return max(1, min(jobs, torch.get_num_threads()))


def run_fits(
    jobs: Sequence[Callable[[], T]],
    *,
    workers: int,
    done: Callable[[int], None] | None = None,
    portable: tuple[Callable[[T], Any], Callable[[Any], T]] | None = None,
    cancel: CancelFn = never,
) -> list[T]:
    """Run ``jobs`` and return their results in the jobs' order.

    Args:
        jobs: Independent fits (each draws from its own generator, see the module's note).
        workers: Threads or processes; with one, the jobs run in turn on the calling thread with torch's threads as
            they are. With more, each runs torch on one thread for the duration, and the count is restored after.
        done: Called on the calling thread with the number of jobs finished so far, after each one.
        portable: ``(pack, unpack)``, a result to plain data and back: given, and where forking is allowed
            (:func:`.fit_processes.fork_safe`), the jobs run in forked processes (:mod:`.fit_processes`), which the
            GIL does not hold back; without it, in threads. Not for jobs that use CUDA (a forked child cannot). A
            ``RuntimeError`` raised in a child (torch refusing to train there) runs the jobs again in threads, and
            this process forks no more fits (a job's own ``RuntimeError`` then comes from the threads, at twice the
            time); a child that died raises :class:`.fit_processes.FitProcessError` (in a thread it would have
            taken this process with it).
        cancel: Polled while forked children run (threads and the calling thread poll it inside the jobs).

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
    if portable is not None and fork_safe():
        pack, unpack = portable
        try:
            return run_forked(jobs, workers=workers, pack=pack, unpack=unpack, done=done, cancel=cancel)
        except RuntimeError as e:  # torch refusing to train in a forked child: the fits again, in threads
            give_up_forking(e)  # (not FitProcessError: a job whose child died would take this process down in a thread)
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
