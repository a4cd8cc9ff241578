"""``workbench classify``: an exported bundle run on log files, no session needed.

A default-family bundle is read and run in NumPy alone (:func:`training.load_scoring_bundle`): importing PyTorch was
3.5 s of a ten-minute run's 7.8 s, and the robot's fleet scores file by file. Bundles of other families load with
:func:`training.load_bundle` and score along the session's path (:func:`workbench.cycle.score_logs`). This module
imports neither PyTorch nor the session's scoring path at its top.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import pandas as pd

from sessions import (
    PREDICTION_TOPIC,
    IngestError,
    IngestOptions,
    LogClock,
    PoseTrack,
    Source,
    TerrainPredictions,
    WorkbenchError,
    align,
    check_new_target,
    path_topics,
    per_log_paths,
    plan_sources,
    read_source,
    refuse_existing,
    write_frame,
    write_terrain_mcap,
)
from training import (
    MAX_DWELL_S,
    BundleError,
    ScoringBundle,
    SpectralSteps,
    TerrainFilter,
    load_scoring_bundle,
    log_frames,
    unseen_words,
)

from ..cycle import ChecksSummary, estimate_disagrees, frame_log_scores, log_change_points
from ..expectations import card_accuracy, file_expectation
from ..maps import best_track, class_colours, first_fix, log_path, terrain_path
from .bundle_checks import read_checks

if TYPE_CHECKING:
    import labeling
    from training import ModelBundle

T = TypeVar("T")
R = TypeVar("R")


OUTPUT_TYPES = (".csv", ".parquet", ".json", ".mcap")  # classify's --out


def prediction_frame(
    log: str, probs: np.ndarray, classes: Sequence[str], rate_hz: float, drift: np.ndarray | None = None
) -> pd.DataFrame:
    """Per-timestep predictions of one log: sample, time, most probable terrain, ``p_<terrain>`` columns and, when
    the model gives one, ``drift`` (how unlike the labelled data the step is; above 1: drifted).

    Args:
        log: The log's name.
        probs: ``(T, K)`` class probabilities.
        classes: The ``K`` terrain names.
        rate_hz: The log's sample rate.
        drift: ``(T,)`` drift scores, or ``None``.
    """
    t = np.arange(len(probs))
    frame = pd.DataFrame(
        {"log": log, "sample": t, "t_s": t / rate_hz, "terrain": np.asarray(classes)[probs.argmax(-1)]}
    )
    for k, c in enumerate(classes):
        frame[f"p_{c}"] = probs[:, k]
    if drift is not None:
        frame["drift"] = np.asarray(drift, np.float32)
    return frame


@dataclass(frozen=True)
class ReadLogs:
    """Log files read for a bundle: per log its name, ``(T, C)`` samples in the bundle's channel order at its rate,
    and its start on the source's clock; and the files refused, each an error naming it."""

    names: tuple[str, ...]
    arrays: tuple[np.ndarray, ...]
    starts: tuple[float, ...]
    errors: tuple[IngestError, ...]
    paths: tuple[str, ...] = ()  # each log's source file
    notes: tuple[str, ...] = ()  # a log renamed so that one name names one run, and from which file
    tracks: tuple[PoseTrack | None, ...] = ()  # each log's best pose track, times from its first sample


def read_logs(
    bundle: ModelBundle | ScoringBundle, files: Sequence[Path], options: IngestOptions, *, jobs: int = 1
) -> ReadLogs:
    """Read log files as ``workbench ingest`` does, aligned at the bundle's rate, in its channel order; ``jobs``
    sources at once, each in a process of its own (reading a log is Python: one core's work)."""
    sources, errors = plan_sources(list(files))
    read = partial(_read_source, float(bundle.rate_hz), tuple(bundle.channels), options)
    names, arrays, starts, paths, tracks = [], [], [], [], []
    for got in in_processes(read, sources, jobs=jobs):
        names += got.names
        arrays += got.arrays
        starts += got.starts
        errors += got.errors
        paths += got.paths
        tracks += got.tracks
    names, notes = _one_name_one_run(names, paths)
    return ReadLogs(
        tuple(names), tuple(arrays), tuple(starts), tuple(errors), tuple(paths), tuple(notes), tuple(tracks)
    )


def _one_name_one_run(names: list[str], paths: list[str]) -> tuple[list[str], list[str]]:
    """Names that each name one run (two files of one stem in two folders: the later one ``NAME-2``, as ``ingest``
    names it), and a note per log renamed."""
    out, notes, taken = [], [], set(names)
    for name, path in zip(names, paths, strict=True):
        if name in out:
            k = 2
            while f"{name}-{k}" in taken:
                k += 1
            taken.add(f"{name}-{k}")
            notes.append(f"two runs are named {name}: the one from {path} is written as {name}-{k}")
            name = f"{name}-{k}"
        out.append(name)
    return out, notes


def _read_source(rate_hz: float, channels: tuple[str, ...], options: IngestOptions, src: Source) -> ReadLogs:
    """One planned source's logs at ``rate_hz`` in ``channels``' order, or the errors that refused them."""
    names, arrays, starts, errors, paths, tracks = [], [], [], [], [], []
    try:
        parsed, _ = read_source(src, options)
    except IngestError as exc:
        return ReadLogs((), (), (), (exc,))
    for p in parsed:
        try:
            a = align(p, replace(options, rate_hz=rate_hz))  # the rate the model was trained at
        except IngestError as exc:
            errors.append(exc)
            continue
        have = [c.name for c in a.channels]
        missing = [c for c in channels if c not in have]
        if missing:
            errors.append(IngestError(src.path, f"lacks channels the model needs: {', '.join(missing[:5])}"))
            continue
        names.append(p.name)
        arrays.append(a.data[:, [have.index(c) for c in channels]])
        starts.append(a.t0)
        paths.append(p.source_path)
        best = best_track(list(p.poses))
        tracks.append(None if best is None else replace(best, times=best.times - a.t0))
    return ReadLogs(tuple(names), tuple(arrays), tuple(starts), tuple(errors), tuple(paths), tracks=tuple(tracks))


def in_processes(fn: Callable[[T], R], items: Sequence[T], *, jobs: int) -> list[R]:
    """``[fn(x) for x in items]`` in that order, in up to ``jobs`` forked processes where there are several items.

    Forked, so each child starts with what the parent loaded (the bundle's arrays, the modules) rather than importing
    it again; on Linux, and in this process elsewhere.
    """
    jobs = min(jobs, len(items))
    if jobs <= 1 or sys.platform != "linux":
        return [fn(x) for x in items]
    from training import end_with_parent

    context = multiprocessing.get_context("fork")
    # a killed classify leaves no worker holding its output pipe (`classify ... | cat` would never end)
    with ProcessPoolExecutor(jobs, mp_context=context, initializer=end_with_parent, initargs=(os.getpid(),)) as pool:
        return list(pool.map(fn, items))


def default_jobs(files: int) -> int:
    """Processes for ``files`` files: one per core this process may use, never more than the files."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    return max(1, min(files, cores))


def score_arrays(
    bundle: ModelBundle | ScoringBundle, arrays: Sequence[np.ndarray], *, jobs: int = 1
) -> list[labeling.LogScores]:
    """Each log scored by the bundle alone, as ``classify`` and the robot score it (no session: no labels, no
    votes): per log a ``labeling.LogScores`` (probabilities, members' agreement, drift). A :class:`ScoringBundle`
    runs in NumPy, ``jobs`` logs at once in processes of their own; a ``ModelBundle`` along the session's scoring
    path, in this process."""
    if isinstance(bundle, ScoringBundle):
        return in_processes(partial(_numpy_scores, bundle), list(arrays), jobs=jobs)
    from training import run_predictor

    from ..cycle import in_memory_features, score_logs

    if bundle.stage2_family().stage2_inputs in ("frames", "windows"):
        # the predictions file holds no surprise: these families' stage 2 never reads stage 1, so it is skipped
        features = in_memory_features(list(arrays), bundle, bundle.spectral)
        surprise = [np.zeros(len(a), np.float32) for a in arrays]
    else:
        outs = run_predictor(bundle.predictor, bundle.normalizer, list(arrays))
        features = [o.lazy(bundle.feature_mode) for o in outs]
        surprise = [o.surprise() for o in outs]
    return score_logs(bundle.classifiers, features, surprise, drift=bundle.drift)


def _numpy_scores(bundle: ScoringBundle, samples: np.ndarray) -> labeling.LogScores:
    """One log's scores from a :class:`ScoringBundle`'s members over its frames."""
    front = bundle.spectral
    steps = SpectralSteps(log_frames(samples, front, transform=bundle.normalizer), len(samples), front)
    chunks = bundle.members.chunks(steps, drift=bundle.drift)
    surprise = np.zeros(len(samples), np.float32)  # the family's stage 2 never reads stage 1: none is written
    return frame_log_scores(chunks, bundle.members.blank(), steps, surprise, drift=bundle.drift is not None)


def load_for_scoring(bundle_dir: Path) -> ModelBundle | ScoringBundle:
    """The bundle in ``bundle_dir`` as the cheapest scorer of files: a default-family bundle's arrays (no PyTorch),
    else the whole bundle.

    Raises:
        BundleError: Missing or damaged files, or a bundle without a classifier.
    """
    bundle = load_scoring_bundle(bundle_dir)
    if bundle is None:
        from training import load_bundle

        bundle = load_bundle(bundle_dir)
        if not bundle.classifiers:
            raise BundleError(f"{bundle_dir}: the bundle has no classifier")
    return bundle


def _finite_only(names: list[str], scored: list, lines: list[str]) -> list[int]:
    """The files whose every probability is finite; an error line for each other one. A NaN is no terrain (its
    argmax reads as the first class), so such a file gets no output at all."""
    kept = []
    for i, (name, s) in enumerate(zip(names, scored, strict=True)):
        bad = int((~np.isfinite(s.probs).all(axis=1)).sum())
        if bad:
            lines.append(f"error: {name}: the model gave {bad:,} step(s) no finite probability; nothing written for it")
        else:
            kept.append(i)
    return kept


def _checks_lines(bundle_dir: Path, card: float | None) -> tuple[ChecksSummary | None, list[str]]:
    """The bundle's checks, and what ``classify`` says of them first: the spot checks (else every check) beside the
    card's estimate, warned of when the estimate lies outside the spot checks' interval by 10 points or more."""
    checks, damaged = read_checks(bundle_dir)
    if checks is None:
        return None, [] if damaged is None else [f"warning: {damaged}"]
    if checks.spot is not None:
        lines = [f"your checks in the session (at export): {checks.spot.words('spot checks')}"]
        if estimate_disagrees(card, checks.spot):
            lines.append(
                f"warning: the card's estimate ({card:.0%}) lies outside your spot checks' interval by 10 points or "
                "more: trust the spot checks"
            )
        return checks, lines
    counted = checks.all or checks.suggested  # a hand-edited file may hold either alone
    if counted is None:
        return None, []
    return checks, [
        f"your checks in the session (at export): {counted.words()}, none of them a spot check (the checks of "
        "suggestions are where the model was doubted, and run low)"
    ]


def classify_files(
    bundle_dir: Path,
    files: Sequence[Path],
    out: Path,
    options: IngestOptions,
    *,
    smooth_s: float | None = None,
    jobs: int | None = None,
):
    """Per-timestep predictions for log files; returns (exit code, lines to print).

    ``out`` is a table (.csv, .parquet, .json) of every log, or an ``.mcap`` file per log on the log's own clock
    (``sessions.terrain_mcap``); an MCAP output that exists is refused before the model runs. ``smooth_s``: the
    probabilities written are forward–backward over an HMM whose terrain lasts that many seconds on average
    (:class:`training.TerrainFilter`); each file's line says the delay the causal filter costs on a robot.
    ``jobs``: files read and scored at once, each in a process of its own (default: one per core); a bundle that runs
    in PyTorch (not the default family) scores in this process.
    """
    if smooth_s is not None and not 0 < smooth_s <= MAX_DWELL_S:
        return 2, [
            f"error: --smooth {smooth_s:g}: the time on a terrain is a number of seconds above 0 and at most "
            f"{MAX_DWELL_S:g} (a day)"
        ]
    if jobs is not None and jobs < 1:
        return 2, [f"error: --jobs {jobs}: the files read at once are a whole number of at least 1"]
    if Path(out).suffix.lower() not in OUTPUT_TYPES:
        return 2, [f"error: {out}: unknown output type {Path(out).suffix!r}; use {', '.join(OUTPUT_TYPES)}"]
    try:
        if Path(out).suffix.lower() != ".mcap":  # an MCAP output's names are per log, checked once they are known
            check_new_target(Path(out))
        bundle = load_for_scoring(bundle_dir)
    except (BundleError, WorkbenchError) as exc:
        return 2, [f"error: {exc}"]
    if options.target_rate is not None and abs(options.target_rate - bundle.rate_hz) > 1e-9:
        return 2, [
            f"error: {bundle_dir}: the model runs at {bundle.rate_hz:g} Hz, so logs are aligned at that rate; "
            f"--rate {options.target_rate:g} would feed it another (leave --rate out)"
        ]
    as_mcap = Path(out).suffix.lower() == ".mcap"
    checks, lines = _checks_lines(bundle_dir, card_accuracy(bundle.metrics))
    if unseen := unseen_words(bundle.metrics.get("unseen_runs")):
        lines.append(f"this bundle on a run it never saw (folds over the session's runs): {unseen}")
    spot = None if checks is None else checks.spot
    jobs = default_jobs(len(files)) if jobs is None else jobs
    read = read_logs(bundle, files, options, jobs=jobs)
    lines += [f"error: {e}" for e in read.errors]
    lines += [f"note: {n}" for n in read.notes]
    names, arrays, starts = list(read.names), list(read.arrays), list(read.starts)
    tracks = list(read.tracks) or [None] * len(names)  # each file's path, for its MCAP file
    paths = per_log_paths(Path(out), names) if as_mcap else []
    try:
        refuse_existing(paths)
    except WorkbenchError as exc:
        return 2, [*lines, f"error: {exc}"]
    if arrays:
        scored = score_arrays(bundle, arrays, jobs=jobs)
        kept = _finite_only(names, scored, lines)
        names, arrays, scored = [names[i] for i in kept], [arrays[i] for i in kept], [scored[i] for i in kept]
        starts, paths = [starts[i] for i in kept], [paths[i] for i in kept] if as_mcap else paths
        tracks = [tracks[i] for i in kept]
        own_surprise = not isinstance(bundle, ScoringBundle) and bundle.stage2_family().stage2_inputs not in (
            "frames",
            "windows",
        )
        for name, a, s in zip(names, arrays, scored, strict=True):  # per file: its drift and what to expect on it
            points = log_change_points(a, s.surprise if own_surprise else None, rate_hz=bundle.rate_hz)
            expect = file_expectation(
                name,
                s.drift,
                bundle.metrics,
                predicted=s.probs.argmax(1),
                change_points=points,
                rate_hz=bundle.rate_hz,
                members=s.agreement,
            )
            if expect is not None:
                lines += [expect.line(), *filter(None, [expect.warning()])]
            if (mine := None if checks is None else checks.per_run.get(name)) is not None:
                lines.append(  # most of them sit where the model was doubted: a fact beside the figure, no verdict
                    f"{name}: your checks in the session's run of this name found the model {mine.words()}; "
                    "suggestions are placed where the model is doubted, so these run low"
                )
                if estimate_disagrees(expect.expected, spot):
                    lines.append(
                        f"warning: {name}: expected accuracy {expect.expected:.0%}, but your spot checks in the "
                        f"session found the model {spot.words('spot checks')}: trust the checks"
                    )
        if smooth_s is not None:
            hmm = TerrainFilter.for_dwell(smooth_s, bundle.rate_hz, len(bundle.classes))
            for name, s in zip(names, scored, strict=True):
                delay = hmm.delay_steps(float(np.median(s.probs.max(axis=1)))) / bundle.rate_hz
                lines.append(
                    f"{name}: smoothed (an HMM, {smooth_s:g} s on a terrain on average); on a robot the causal "
                    f"filter would follow a terrain change {delay:.2f} s late at this file's median confidence"
                )
            scored = [replace(s, probs=hmm.smooth(s.probs).astype(np.float32)) for s in scored]
        kept = _finite_only(names, scored, lines)
        names, scored, starts = [names[i] for i in kept], [scored[i] for i in kept], [starts[i] for i in kept]
        paths = [paths[i] for i in kept] if as_mcap else paths
        tracks = [tracks[i] for i in kept]
        if as_mcap:
            origin = first_fix(tracks)  # the files' GNSS paths in metres from one fix
            colours = class_colours(bundle.classes)
            for name, s, t0, path, track in zip(names, scored, starts, paths, tracks, strict=True):
                clock = LogClock(name, t0, bundle.rate_hz, len(s.probs))
                predictions = TerrainPredictions(tuple(bundle.classes), s.probs, s.drift)
                drawn = None
                if track is not None:  # the path coloured by the model's sure answers
                    drawn_path = log_path(
                        clock,
                        track,
                        list(bundle.classes),
                        [],
                        probs=s.probs,
                        classes=list(bundle.classes),
                        origin=origin,
                    )
                    drawn = terrain_path(drawn_path, colours)
                about = {"bundle": str(bundle_dir)}
                write_terrain_mcap(path, clock, predictions=predictions, about=about, path_drawn=drawn)
                topics = ", ".join([PREDICTION_TOPIC, *path_topics(drawn)])
                lines.append(f"wrote {path}: {name}, topics {topics}, {clock.n_samples} messages, {clock.span()}")
        else:
            frames = [
                prediction_frame(name, s.probs, bundle.classes, bundle.rate_hz, s.drift)
                for name, s in zip(names, scored, strict=True)
            ]
            if frames:
                write_frame(pd.concat(frames), out)
                lines.append(f"wrote predictions for {len(frames)} log(s) to {out}")
    return (2 if any(x.startswith("error:") for x in lines) else 0), lines
