"""A session's logs scored a group at a time in forked processes, one torch thread each, side by side.

A rescoring in one process leaves cores idle: between torch's products the work is many small operations and NumPy
per log (the runs' votes, a frame's answer over its steps) that one thread does. On two cores, one process with two
torch threads scored 10 h of logs (scores alone) in 30.9 s, two processes of one thread each on half the logs in
24.8 s; the whole rescoring went from 34.6 to 30.3 s (``benchmarks/results/speed.md``). More cores gain more.

Each child scores its group with the scoring function the caller gives (``compute_scores``), writes the arrays where
the caller keeps them and sends back their names only: the parent reads them memory-mapped, never a log's scores
through a pipe. Children are forked (``training.run_forked``): they start with the parent's modules and the
session's memory-mapped caches, and take a SQLite connection of their own (``Session.after_fork``), forked while no
other thread is inside a query (``Session.fork_guard``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import labeling
from sessions import LogInfo, Session
from training import drop_pages

from .score_files import GroupFirst, Scored, kept_array, kept_scores, log_groups, score_arrays, write_array
from .scores import SessionScores, stage1_embedding

FORK_STEPS = 1 << 18  # samples of logs a process must have to score before another is forked (44 min at 100 Hz)
TASKS_PER_PROCESS = 2  # groups per process: one that ends early leaves its process another to take


@dataclass(frozen=True)
class GroupScored:
    """What a child sends back for its group: the versions it scored with and the names of the arrays it wrote.

    Attributes:
        predictor: Predictor version the scores come from.
        classifier: Classifier version (``None``: stage 1 only).
        classes: Class names of the probabilities' last axis.
        span: Samples one step's prediction reads (``SessionScores.span``).
        arrays: Per log id, the names of the arrays written for it.
    """

    predictor: int | None
    classifier: int | None
    classes: tuple[str, ...]
    span: int
    arrays: dict[int, tuple[str, ...]]


def scoring_processes(logs: Sequence[LogInfo], *, fork_steps: int | None = None, min_cores: int = 2) -> int:
    """Processes to score ``logs`` in: one per core this process may use, but only as many as have ``fork_steps``
    samples each to score (default :data:`FORK_STEPS`; a fork, and the session read again in each child, cost more
    than minutes of logs take), and one where this process may use fewer than ``min_cores`` cores or forking is not
    allowed (``training.forking``: Linux only, ``WORKBENCH_FIT_PROCESSES=0`` turns it off)."""
    from training import forking

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    if not forking() or cores < min_cores:
        return 1
    each = FORK_STEPS if fork_steps is None else fork_steps
    return max(1, min(cores, len(logs), sum(x.n_samples for x in logs) // max(1, each)))


def task_steps(logs: Sequence[LogInfo], processes: int, *, group_steps: int) -> int:
    """Samples per group when ``processes`` share ``logs``: a few groups each, never more than ``group_steps``."""
    total = sum(x.n_samples for x in logs)
    return max(1, min(group_steps, math.ceil(total / (processes * TASKS_PER_PROCESS))))


def score_groups_forked(
    session: Session,
    groups: Sequence[Sequence[int]],
    *,
    score: Callable[..., SessionScores],
    keep: Callable[[int, labeling.LogScores], Sequence[str]],
    window: int,
    processes: int,
    cancel: Callable[[], bool],
) -> list[GroupScored]:
    """Score each group of log ids in a forked child, ``processes`` at a time.

    Args:
        session: The session (the children give themselves a connection of their own).
        groups: Log ids scored together.
        score: ``compute_scores`` or what stands for it, called in the child as
            ``score(session, log_ids=group, window=window, tracks=False)``.
        keep: Called in the child for each log scored: writes its arrays and returns their names.
        window: The tracks' smoothing, in samples.
        processes: Children at a time.
        cancel: Polled while the children run; when it answers true they are ended and ``training.Cancelled`` is
            raised.

    Returns:
        Per group, what its child wrote.

    Raises:
        training.Cancelled: ``cancel`` answered true.
        Exception: A child's exception, as it was raised there (a child that died: ``FitProcessError``).
    """
    from training import run_forked

    def job(group: Sequence[int]) -> Callable[[], GroupScored]:
        def run() -> GroupScored:
            from threadpoolctl import threadpool_limits

            threadpool_limits(1)  # NumPy's BLAS too: two threads in each of the children would share the cores
            session.after_fork()
            part = score(session, log_ids=list(group), window=window, tracks=False)
            arrays = {i: tuple(keep(i, s)) for i, s in part.scores.items()}
            return GroupScored(part.predictor, part.classifier, tuple(part.classes), int(part.span), arrays)

        return run

    return run_forked(
        [job(g) for g in groups],
        workers=processes,
        pack=lambda x: x,
        unpack=lambda x: x,
        cancel=cancel,
        what="log group",
        fork_guard=session.fork_guard,
        warm=False,
    )


@dataclass(frozen=True)
class _Group:
    """Logs scored together, sized as one (for :func:`log_groups` to batch groups as it groups logs)."""

    logs: list[LogInfo]

    @property
    def n_samples(self) -> int:
        return sum(x.n_samples for x in self.logs)


def _batches(logs: Sequence[LogInfo], processes: int, group_steps: int) -> list[list[_Group]]:
    """``logs`` cut into a few groups per process, the groups into batches: a batch holds the lane as long as one
    process's group of ``group_steps`` would, the processes' share together."""
    tasks = log_groups(logs, group_steps=task_steps(logs, processes, group_steps=group_steps))
    return log_groups([_Group(g) for g in tasks], group_steps=group_steps * processes)


def _keep(folder: Path, log_id: int, s: labeling.LogScores) -> list[str]:
    """In a child: write a log's arrays to ``folder``; their names."""
    arrays = score_arrays(s)
    for n, a in arrays.items():
        write_array(folder, log_id, n, a)
    return sorted(arrays)


def _rank_kind(
    folder: Path, ids: Sequence[int], scores: dict[int, labeling.LogScores], kind: str, window: int
) -> list[int]:
    """One kind's tracks of every log ranked over the session and written; the logs that have it."""
    ranked = labeling.normalised_tracks([scores[i] for i in ids], window=window, kinds=(kind,))
    has = []
    for i, t in zip(ids, ranked, strict=True):
        if kind in t:
            write_array(folder, i, f"track.{kind}", t[kind])
            has.append(i)
    del ranked
    for s in scores.values():  # the ranking read every log's kept scores: not held resident for the next kind
        for array in (s.surprise, s.probs, s.disagreement, s.drift, s.agreement):
            if array is not None:
                drop_pages(array)
    return has


def rank_tracks(
    session: Session,
    folder: Path,
    ids: Sequence[int],
    scores: dict[int, labeling.LogScores],
    run: Callable[..., Any],
    stop: Callable[[], bool],
    window: int,
    processes: int,
) -> list[list[int]] | None:
    """Per kind (``labeling.KINDS``), the logs whose track was ranked and written: one kind of every log at a time
    (a fleet's tracks of every kind are gigabytes), in ``processes`` forked children where there are several;
    ``None`` when stopped."""
    from training import Cancelled, run_forked

    if processes <= 1:
        out = []
        for kind in labeling.KINDS:
            if stop():
                return None
            out.append(_rank_kind(folder, ids, scores, kind, window))
        return out
    jobs = [partial(_rank_kind, folder, ids, scores, kind, window) for kind in labeling.KINDS]
    try:
        return run(
            run_forked,
            jobs,
            workers=processes,
            pack=list,
            unpack=list,
            cancel=stop,
            what="track kind",
            fork_guard=session.fork_guard,
            warm=False,
        )
    except Cancelled:
        return None


def scored_forked(
    session: Session,
    logs: Sequence[LogInfo],
    score: Callable[..., SessionScores],
    run: Callable[..., Any],
    cancel: Callable[[], bool],
    versions: tuple[int, int | None],
    folder: Path,
    window: int,
    group_steps: int,
    processes: int,
) -> Scored | None:
    """A session's logs scored in ``processes`` forked children, a few groups per process, a batch of groups through
    ``run`` at a time (the server's torch lane: other work on it goes between two batches), their arrays written to
    ``folder`` and read back memory-mapped.

    Args:
        session: The session.
        logs: The logs to score.
        score: ``compute_scores`` or what stands for it (:func:`score_groups_forked`).
        run: How each batch runs (``LANE.run``).
        cancel: Polled before each batch and while the children run: ``None`` is returned when it says so.
        versions: The active ``(predictor, classifier)``: a child that scored with others ends the scoring.
        folder: Where the kept scores are written.
        window: The tracks' smoothing, in samples.
        group_steps: Samples of logs one process's group may hold.
        processes: Children at a time.

    Returns:
        What the groups agree on, each log's scores, the suggestions' embeddings and the arrays' names per log;
        ``None`` when cancelled or when the active models changed.
    """
    from training import Cancelled

    batches = _batches(logs, processes, group_steps)
    keep = partial(_keep, folder)
    first: GroupFirst | None = None
    scores: dict[int, labeling.LogScores] = {}
    names: dict[str, list[str]] = {}
    for batch in batches:
        if cancel():
            return None
        try:
            parts = run(
                score_groups_forked,
                session,
                [[x.id for x in g.logs] for g in batch],
                score=score,
                keep=keep,
                window=window,
                processes=processes,
                cancel=cancel,
            )
        except Cancelled:
            return None
        for part in parts:
            if (part.predictor, part.classifier) != versions:
                return None
            first = first or GroupFirst(part.predictor, part.classifier, part.classes, part.span)
            for log_id, kept in part.arrays.items():
                arrays = {n: kept_array(folder / f"{log_id:06d}.{n}.npy") for n in kept}
                scores[log_id] = kept_scores(arrays)
                names[str(log_id)] = list(kept)
    return first, scores, run(_embeddings, session, [x for x in logs if x.id in scores]), names


def _embeddings(session: Session, logs: Sequence[LogInfo]) -> dict:
    """The suggestions' stage-1 rows of ``logs`` from the stage-1 cache (memory maps only), as ``compute_scores``
    gives them."""
    from training import load_bundle

    from .stage_inputs import stage1_outputs

    p_version = session.active_model("predictor")
    assert p_version is not None
    outs = stage1_outputs(session, p_version, load_bundle(session.path / p_version.path), logs)
    return {x.id: stage1_embedding(outs[x.id]) for x in logs}


def scored_in_processes(
    session: Session,
    logs: Sequence[LogInfo],
    score: Callable[..., SessionScores],
    *,
    processes: int,
    folder: Path,
    group_steps: int,
) -> Iterator[tuple[LogInfo, labeling.LogScores]]:
    """Each log with its scores, in the order of ``logs``, scored in ``processes`` forked children a few groups per
    process (``workbench export --predictions``'s pass over every log): each batch's arrays are written to ``folder``
    and handed on memory-mapped, and their files removed once the next batch is asked for (a mapping outlives its
    file's name).

    Args:
        session: The session.
        logs: The logs, in the order they are handed on.
        score: Called in each child as ``score(session, log_ids=..., window=..., tracks=False)``.
        processes: Children at a time.
        folder: An empty folder for the batches' arrays.
        group_steps: Samples of logs one process's group may hold.
    """
    batches = _batches(logs, processes, group_steps)
    keep = partial(_keep, folder)
    for batch in batches:
        groups = [[x.id for x in g.logs] for g in batch]
        parts = score_groups_forked(
            session, groups, score=score, keep=keep, window=0, processes=processes, cancel=lambda: False
        )
        written = []
        for g, part in zip(batch, parts, strict=True):
            for x in g.logs:
                paths = [folder / f"{x.id:06d}.{n}.npy" for n in part.arrays[x.id]]
                written += paths
                yield (
                    x,
                    kept_scores({n: kept_array(p) for n, p in zip(part.arrays[x.id], paths, strict=True)}),
                )
        for p in written:
            p.unlink(missing_ok=True)
