"""Independent fits in forked processes, one torch thread each, for machines with more cores than threads can use.
(:func:`run_forked` runs any independent jobs so: the workbench scores hours of logs with it too.)

Threads share one interpreter: a fold network's step is many small torch ops, and between two ops the thread needs
the GIL back. Sampled on 2 cores (py-spy ``--gil``), a fit thread held the GIL in 18 % of its active samples, so
threads top out near five fits' worth of cores however many there are, and waiting for the GIL costs more the more
threads ask (a first model's ten fits: 1.24x from 16 cores over 2,
``benchmarks/results/raw/fleet/gpu-and-cores-h200-2026-11-28.md``). A forked child shares nothing but the memory it
inherits: the session's memory-mapped frames and the self-training pool are read in place (copy-on-write, never
written), and only the result travels back, as plain arrays.

Forking is Linux's: elsewhere, or with ``WORKBENCH_FIT_PROCESSES=0``, the fits run in threads
(:mod:`.fit_threads`). A child enters no OpenMP parallel region (one torch thread), which is what makes a fork after
the parent's own parallel regions safe with GNU OpenMP. Autograd is the other limit: a torch built with CUDA, on a
machine with a GPU, starts a thread per GPU at the process's first backward pass and from then on refuses a backward
pass in any child forked after it (seen on a lent H200: every fork failed). :func:`fork_safe` asks a child first and
the fits fall back to threads where it fails; :func:`hide_gpus` keeps a CPU-only run clear of that (a run on the
CPU has no use for the GPU, and a torch that sees none starts no such thread).
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import traceback
import warnings
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, nullcontext
from multiprocessing.connection import Connection, wait
from typing import Any, TypeVar

import torch

from ..training_errors import TrainingError
from .parent_death import end_with_parent
from .progress import CancelFn, Cancelled, never

T = TypeVar("T")

POLL_S = 0.25  # how often a cancel is polled while the fits run


def forking() -> bool:
    """Whether fits may run in forked processes here."""
    return sys.platform == "linux" and os.environ.get("WORKBENCH_FIT_PROCESSES", "1") != "0"


_UNSAFE: list[bool] = []  # set once a child's backward pass failed: autograd's threads, once started, stay


def hide_gpus() -> bool:
    """For a run that trains on the CPU only: hide the GPUs from torch before anything asks torch about them, so that
    its autograd starts no GPU threads and the fits can fork (:func:`fork_safe`). Returns whether they were hidden
    (not where torch has initialised CUDA, nor where ``CUDA_VISIBLE_DEVICES`` is set already; where torch has only
    counted the GPUs, the variable comes too late and :func:`fork_safe` finds that out)."""
    if not forking() or "CUDA_VISIBLE_DEVICES" in os.environ or torch.cuda.is_initialized():
        return False
    os.environ["CUDA_VISIBLE_DEVICES"] = ""
    return True


def fork_safe() -> bool:
    """Whether a forked child can train: a child forked now runs one backward pass (a few milliseconds)."""
    if _UNSAFE or not forking():
        return False
    pid = os.fork()
    if pid == 0:  # the child: report by exit code only, and leave without running the parent's clean-up
        code = 1
        try:
            torch.set_num_threads(1)
            x = torch.ones(2, requires_grad=True)
            (x * x).sum().backward()
            code = 0
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        _UNSAFE.append(True)
        return False
    return True


def give_up_forking(reason: BaseException) -> None:
    """Fork no more fits in this process (they run in threads from now on), and say why once."""
    if not _UNSAFE:
        warnings.warn(f"stage 2's fits run in threads from now on: a forked fit failed ({reason})", stacklevel=2)
    _UNSAFE.append(True)


class FitProcessError(TrainingError):
    """A fit's process ended without a result (killed, or out of memory): one line for the person."""


def _warm() -> None:
    """What every fit's first step would import, imported once here so that each child inherits it: an optimizer's
    first step loads ``torch._dynamo`` (1.1 s)."""
    p = torch.zeros(1, requires_grad=True)
    opt = torch.optim.AdamW([p], lr=0.0, fused=True)
    p.grad = torch.zeros(1)
    opt.step()


def _child(job: Callable[[], Any], pack: Callable[[Any], Any], conn: Connection, parent: int) -> None:
    end_with_parent(parent)
    torch.set_num_threads(1)
    try:
        out: tuple[str, Any] = ("ok", pack(job()))
    except BaseException as e:  # whatever the fit raised goes back to the caller
        out = ("error", e, traceback.format_exc())
    try:
        conn.send(out)
    except Exception as e:  # what does not pickle goes back as text; the caller then runs the fits in threads
        what = f"{type(out[1]).__name__}: {out[1]}" if out[0] == "error" else "its result"
        conn.send(("error", RuntimeError(f"a forked fit could not send {what} back ({e})"), traceback.format_exc()))
    conn.close()


def run_forked(
    jobs: Sequence[Callable[[], T]],
    *,
    workers: int,
    pack: Callable[[T], Any],
    unpack: Callable[[Any], T],
    done: Callable[[int], None] | None = None,
    cancel: CancelFn = never,
    what: str = "fit",
    fork_guard: Callable[[], AbstractContextManager] = nullcontext,
    warm: bool = True,
) -> list[T]:
    """Run ``jobs`` in at most ``workers`` forked children at a time; their results in the jobs' order.

    Args:
        jobs: Independent jobs: fits, each drawing from its own generator (the same arithmetic as one after the
            other), or a session's logs scored a group at a time.
        workers: Children at a time.
        pack: Turns a job's result into what pickles as plain data (a network into its weights), in the child.
        unpack: The inverse, in the caller.
        done: Called on the calling thread with the number of jobs finished so far, after each one.
        cancel: Polled every ``POLL_S`` seconds; when it answers true the children are ended.
        what: What a job is, for the messages (``"fit"``).
        fork_guard: Held while each child is forked: a lock that keeps the parent's other threads out of what the
            children use (a session's SQLite connection), so that no child starts with it half-used.
        warm: Import what a fit's first optimizer step imports before forking, once for every child (jobs that
            train nothing skip its second).

    Returns:
        Each job's result, unpacked.

    Raises:
        Cancelled: ``cancel`` answered true.
        FitProcessError: A child ended without sending a result.
        Exception: The first job's exception, as the job raised it; the other children are ended.
    """
    if warm:
        _warm()
    context = multiprocessing.get_context("fork")
    waiting = list(range(len(jobs)))
    running: dict[Connection, tuple[int, Any]] = {}
    results: list[T | None] = [None] * len(jobs)
    finished = 0
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                i = waiting.pop(0)
                receive, send = context.Pipe(duplex=False)
                child = context.Process(
                    target=_child, args=(jobs[i], pack, send, os.getpid()), daemon=True, name=f"{what}-{i}"
                )
                with fork_guard():
                    child.start()
                send.close()  # the child holds the only writer: its end reads as EOF if it dies
                running[receive] = (i, child)
            for conn in wait(list(running), timeout=POLL_S):
                i, child = running.pop(conn)
                try:
                    message = conn.recv()
                except EOFError:
                    child.join()
                    raise FitProcessError(
                        f"{what} {i + 1} of {len(jobs)} ended without a result (exit code {child.exitcode}; "
                        f"out of memory?); WORKBENCH_FIT_PROCESSES=0 runs the {what}s in this process"
                    ) from None
                finally:
                    conn.close()
                child.join()
                if message[0] == "error":
                    error = message[1]
                    error.add_note(f"raised in the {what}'s forked process:\n{message[2]}")
                    raise error
                results[i] = unpack(message[1])
                finished += 1
                if done:
                    done(finished)
            if cancel():
                raise Cancelled(f"cancelled while the {what}s ran")
    finally:
        for conn, (_, child) in running.items():
            child.terminate()
            child.join()
            conn.close()
    return results  # type: ignore[return-value]
