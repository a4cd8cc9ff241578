"""Export for the robot: model bundle + model card + ONNX (checked against PyTorch on real logs) + label files."""

from __future__ import annotations

import shutil
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pandas as pd

import labeling
from sessions import (
    LABEL_TOPIC,
    PREDICTION_TOPIC,
    IngestError,
    IngestOptions,
    LogClock,
    LogInfo,
    ModelVersion,
    Session,
    TerrainPredictions,
    WorkbenchError,
    align,
    check_new_target,
    per_log_paths,
    plan_sources,
    read_source,
    refuse_existing,
    safe_file_name,
    write_frame,
    write_terrain_mcap,
)
from training import (
    MAX_DWELL_S,
    BundleError,
    ModelBundle,
    TerrainFilter,
    load_bundle,
    run_predictor,
    unseen_words,
)

from ..cycle import ChecksSummary, estimate_disagrees
from ..expectations import card_accuracy, file_expectation, stretch_share
from .bundle_checks import read_checks, write_checks
from .export_staging import check_target, staged
from .model_card import model_card
from .predictions_stream import PredictionsWriter, scored_logs, with_drift_column

ONNX_TOLERANCE = 1e-4
CHECK_SAMPLES = 1500  # per log, for the ONNX check: a per-sample loop in onnxruntime


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


def export_all(
    session: Session, out: Path, *, predictions: bool = False, mcap: bool = False, frames: bool = False
) -> list[tuple[Path, str]]:
    """Write the active model and the labels to a new folder ``out``; with ``predictions``, per-timestep predictions
    of every log as Parquet; with ``mcap``, an MCAP file per log (the model's terrain and the labels, on the log's
    clock) in ``out/mcap``; with ``frames``, the camera frames of the labelled segments in ``out/frames``, a folder
    per terrain, and their index (``frames/index.csv``).

    Returns:
        What was written, one (path, description) per item.
    """
    from ..cycle import active_bundle

    out = Path(out)
    check_target(out)  # before any work: a dangling link failed only at the rename, after the whole export
    version, bundle = active_bundle(session)
    # written under a temporary name and renamed when whole: a refused export leaves no half-written folder
    with staged(out) as tmp:
        written = _write_export(session, tmp, version, bundle, predictions=predictions, mcap=mcap, frames=frames)
    return [(out / path.relative_to(tmp), what) for path, what in written]


def _write_export(
    session: Session,
    out: Path,
    version: ModelVersion,
    bundle: ModelBundle,
    *,
    predictions: bool,
    mcap: bool,
    frames: bool,
) -> list[tuple[Path, str]]:
    from training import check_onnx, export_onnx

    from ..cycle import FigureTally, checks_summary, model_logs, score_session, signal_change_points

    written: list[tuple[Path, str]] = []
    streamed: list[tuple[Path, str]] = []  # the predictions, then each log's MCAP: listed after the bundle's files
    shutil.copytree(session.path / version.path, out / "bundle")
    labelled_logs = {g.log_id for g in session.segments()}
    drifted: dict[str, float] = {}
    unlabelled: dict[str, tuple[float, int]] = {}  # the logs nobody labelled: what the model expects there
    agree, agree_steps = 0.0, 0  # their steps predicted as their stretch's most predicted terrain
    members, members_steps, members_logs = 0.0, 0, 0  # their steps' members' agreement (the Data tab's figure)
    logs = model_logs(session, bundle.channels)
    tally = FigureTally(session, version.id)  # how right the session is, from the spot checks of this version
    if predictions or mcap or bundle.drift is not None:  # every log scored, a group at a time, handed on per log
        table = PredictionsWriter(out / "predictions.parquet") if predictions else None
        if mcap:
            (out / "mcap").mkdir()
            mcap_paths = dict(
                zip(
                    (x.id for x in logs),
                    per_log_paths(out / "mcap" / "terrain.mcap", [x.name for x in logs], each=True),
                    strict=True,
                )
            )
        for log, s in scored_logs(logs, lambda ids: score_session(session, ids)):
            if s.probs is not None:
                tally.add(log.id, s.probs)
            if (share := labeling.drifted_share(s.drift)) is not None:
                drifted[log.name] = share
            if log.id not in labelled_logs and bundle.drift is not None:
                e = file_expectation(log.name, s.drift, bundle.metrics)
                if e is not None and e.expected is not None:
                    unlabelled[log.name] = (e.expected, len(s.drift))
                if s.agreement is not None and len(s.agreement):
                    members += float(np.sum(s.agreement, dtype=np.float64))
                    members_steps += len(s.agreement)
                    members_logs += 1
                if s.probs is not None and len(s.probs):
                    cuts = signal_change_points(session, log)
                    agree += stretch_share(s.probs.argmax(1), cuts, rate_hz=log.rate_hz) * len(s.probs)  # type: ignore[operator]
                    agree_steps += len(s.probs)
            if table is not None:
                frame = prediction_frame(log.name, s.probs, bundle.classes, bundle.rate_hz, s.drift)
                table.write(with_drift_column(frame, bundle.drift is not None))
            if mcap:
                streamed.append(_write_mcap(session, mcap_paths[log.id], log, version, bundle, s))
        if table is not None:
            empty = prediction_frame("", np.zeros((0, len(bundle.classes)), np.float32), bundle.classes, 1.0)
            table.close(with_drift_column(empty, bundle.drift is not None))
            streamed.insert(0, (table.path, "per-timestep predictions"))
    agreement = agree / agree_steps if unlabelled and agree_steps else None
    card = model_card(
        bundle,
        version=version.id,
        session=session.path.name,
        drifted=drifted,
        unlabelled=unlabelled,
        unlabelled_agreement=agreement,
        unlabelled_members=(members / members_steps, members_logs) if members_steps else None,
        checks=(checks := checks_summary(session)),
        figure=tally.figures().session if predictions or mcap or bundle.drift is not None else None,
        logs=len(logs),
    )
    (out / "bundle" / "MODEL_CARD.md").write_text(card)
    write_checks(out / "bundle", checks, names={x.id: x.name for x in logs})
    written.append((out / "bundle", f"model bundle v{version.id} (safetensors + model.json + MODEL_CARD.md)"))
    onnx = export_onnx(bundle, out / "classifier_stream.onnx")
    worst = max(check_onnx(onnx, bundle, session.samples(x.id, 0, CHECK_SAMPLES)) for x in logs[:2])
    if worst > ONNX_TOLERANCE:
        raise WorkbenchError(f"ONNX export differs from PyTorch by {worst:.2e} (> {ONNX_TOLERANCE}); not exported")
    written.append((onnx, f"streaming classifier, checked with onnxruntime: max |Δp| {worst:.1e} on real logs"))
    for suffix in (".csv", ".parquet", ".json"):
        written.append((session.export_labels(out / f"labels{suffix}"), "label segments"))
    written += streamed
    if frames:
        written.append(write_labelled_frames(session, out / "frames"))
    return written


def write_labelled_frames(session: Session, folder: Path) -> tuple[Path, str]:
    """The camera frames inside labelled segments, as the JPEGs the session keeps: ``folder/TERRAIN/LOG-camK-T.jpg``
    (``T``: ms from the log's start), the layout image-classification tools read, and ``folder/index.csv`` with each
    frame's log, camera topic, time and terrain."""
    folder.mkdir()
    logs = {x.id: x for x in session.logs()}
    cameras = {log_id: session.cameras(log_id) for log_id in logs}
    rows = []
    for seg in session.segments():
        log = logs[seg.log_id]
        for cam in cameras[log.id]:
            a, b = seg.start / log.rate_hz, seg.stop / log.rate_hz
            for number in session.camera_frames_between(log.id, a, b, camera=cam.index):
                frame = session.camera_frame_by_number(log.id, number, camera=cam.index)
                name = f"{safe_file_name(log.name)}-cam{cam.index}-{round(frame.t * 1000):08d}.jpg"
                file = Path(safe_file_name(seg.terrain)) / name
                (folder / file.parent).mkdir(exist_ok=True)
                (folder / file).write_bytes(frame.jpeg)
                rows.append((file.as_posix(), log.name, cam.topic, frame.t, log.t0 + frame.t, seg.terrain))
    columns = ["file", "log", "camera", "t_s", "time", "terrain"]
    write_frame(pd.DataFrame(rows, columns=columns), folder / "index.csv")
    cams = "no log with labels has a camera" if not rows else f"{len(rows)} frames of labelled segments"
    return folder, f"camera frames, a folder per terrain ({cams}; index.csv)"


def _write_mcap(
    session: Session, path: Path, log: LogInfo, version: ModelVersion, bundle: ModelBundle, s: labeling.LogScores
) -> tuple[Path, str]:
    """One log's MCAP file: its terrain per sample and its labels, on the log's own clock."""
    write_terrain_mcap(
        path,
        LogClock.of(log),
        predictions=TerrainPredictions(tuple(bundle.classes), s.probs, s.drift),
        labels=session.segments(log.id),
        about={"model_version": str(version.id), "session": session.path.name, "source_file": log.source_path},
    )
    return path, f"{log.name}: topics {PREDICTION_TOPIC} and {LABEL_TOPIC} on the log's clock"


@dataclass(frozen=True)
class ReadLogs:
    """Log files read for a bundle: per log its name, ``(T, C)`` samples in the bundle's channel order at its rate,
    and its start on the source's clock; and the files refused, each an error naming it."""

    names: tuple[str, ...]
    arrays: tuple[np.ndarray, ...]
    starts: tuple[float, ...]
    errors: tuple[IngestError, ...]


def read_logs(bundle: ModelBundle, files: Sequence[Path], options: IngestOptions) -> ReadLogs:
    """Read log files as ``workbench ingest`` does, aligned at the bundle's rate, in its channel order."""
    sources, errors = plan_sources(list(files))
    names, arrays, starts = [], [], []
    for src in sources:
        try:
            parsed, _ = read_source(src, options)
        except IngestError as exc:
            errors.append(exc)
            continue
        for p in parsed:
            try:
                a = align(p, replace(options, rate_hz=bundle.rate_hz))  # the rate the model was trained at
            except IngestError as exc:
                errors.append(exc)
                continue
            have = [c.name for c in a.channels]
            missing = [c for c in bundle.channels if c not in have]
            if missing:
                errors.append(IngestError(src.path, f"lacks channels the model needs: {', '.join(missing[:5])}"))
                continue
            names.append(p.name)
            arrays.append(a.data[:, [have.index(c) for c in bundle.channels]])
            starts.append(a.t0)
    return ReadLogs(tuple(names), tuple(arrays), tuple(starts), tuple(errors))


def score_arrays(bundle: ModelBundle, arrays: Sequence[np.ndarray]) -> list:
    """Each log scored by the bundle alone, as ``classify`` and the robot score it (no session: no labels, no
    votes): per log a ``labeling.LogScores`` (probabilities, members' agreement, drift)."""
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
    bundle_dir: Path, files: Sequence[Path], out: Path, options: IngestOptions, *, smooth_s: float | None = None
):
    """Per-timestep predictions for log files; returns (exit code, lines to print).

    ``out`` is a table (.csv, .parquet, .json) of every log, or an ``.mcap`` file per log on the log's own clock
    (``sessions.terrain_mcap``); an MCAP output that exists is refused before the model runs. ``smooth_s``: the
    probabilities written are forward–backward over an HMM whose terrain lasts that many seconds on average
    (:class:`training.TerrainFilter`); each file's line says the delay the causal filter costs on a robot.
    """
    if smooth_s is not None and not 0 < smooth_s <= MAX_DWELL_S:
        return 2, [
            f"error: --smooth {smooth_s:g}: the time on a terrain is a number of seconds above 0 and at most "
            f"{MAX_DWELL_S:g} (a day)"
        ]
    if Path(out).suffix.lower() not in OUTPUT_TYPES:
        return 2, [f"error: {out}: unknown output type {Path(out).suffix!r}; use {', '.join(OUTPUT_TYPES)}"]
    try:
        if Path(out).suffix.lower() != ".mcap":  # an MCAP output's names are per log, checked once they are known
            check_new_target(Path(out))
        bundle = load_bundle(bundle_dir)
    except (BundleError, WorkbenchError) as exc:
        return 2, [f"error: {exc}"]
    if not bundle.classifiers:
        return 2, [f"error: {bundle_dir}: the bundle has no classifier"]
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
    read = read_logs(bundle, files, options)
    lines += [f"error: {e}" for e in read.errors]
    names, arrays, starts = list(read.names), list(read.arrays), list(read.starts)
    paths = per_log_paths(Path(out), names) if as_mcap else []
    try:
        refuse_existing(paths)
    except WorkbenchError as exc:
        return 2, [*lines, f"error: {exc}"]
    if arrays:
        from ..cycle import log_change_points

        scored = score_arrays(bundle, arrays)
        kept = _finite_only(names, scored, lines)
        names, arrays, scored = [names[i] for i in kept], [arrays[i] for i in kept], [scored[i] for i in kept]
        starts, paths = [starts[i] for i in kept], [paths[i] for i in kept] if as_mcap else paths
        own_surprise = bundle.stage2_family().stage2_inputs not in ("frames", "windows")
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
        if as_mcap:
            for name, s, t0, path in zip(names, scored, starts, paths, strict=True):
                clock = LogClock(name, t0, bundle.rate_hz, len(s.probs))
                predictions = TerrainPredictions(tuple(bundle.classes), s.probs, s.drift)
                write_terrain_mcap(path, clock, predictions=predictions, about={"bundle": str(bundle_dir)})
                lines.append(
                    f"wrote {path}: {name}, topic {PREDICTION_TOPIC}, {clock.n_samples} messages, {clock.span()}"
                )
        else:
            frames = [
                prediction_frame(name, s.probs, bundle.classes, bundle.rate_hz, s.drift)
                for name, s in zip(names, scored, strict=True)
            ]
            if frames:
                write_frame(pd.concat(frames), out)
                lines.append(f"wrote predictions for {len(frames)} log(s) to {out}")
    return (2 if any(x.startswith("error:") for x in lines) else 0), lines
