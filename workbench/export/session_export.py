"""Export for the robot: model bundle + model card + ONNX (checked against PyTorch on real logs) + label files.

``classify`` (a bundle on log files, no session) lives in :mod:`.file_classify`."""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

import labeling
from sessions import (
    LABEL_TOPIC,
    PREDICTION_TOPIC,
    LogClock,
    LogInfo,
    ModelVersion,
    Session,
    TerrainPath,
    TerrainPredictions,
    WorkbenchError,
    path_topics,
    per_log_paths,
    safe_file_name,
    write_frame,
    write_terrain_mcap,
)
from training import (
    ModelBundle,
)

from ..expectations import file_expectation, stretch_share
from ..maps import MAP_FILE, TerrainMap
from . import predictions_stream
from .bundle_checks import write_checks
from .export_staging import check_target, staged
from .file_classify import prediction_frame
from .model_cards import model_card
from .predictions_stream import PredictionsWriter, scored_logs, with_drift_column

if TYPE_CHECKING:
    from ..cycle import SessionScores

ONNX_TOLERANCE = 1e-4
CHECK_SAMPLES = 1500  # per log, for the ONNX check: a per-sample loop in onnxruntime
# The export's scoring forks a process per core only where there are more than two: on two cores 102.4 h exported in
# 173-178 s forked against 148-154 s in one process (benchmarks/results/fleet.md), the parent writing each batch
# while its children wait; a Retrain's rescoring, which ranks the tracks in its children too, gains there
EXPORT_MIN_CORES = 3


def export_all(
    session: Session,
    out: Path,
    *,
    predictions: bool = False,
    mcap: bool = False,
    frames: bool = False,
    taught: bool = True,
    say: Callable[[str], None] | None = None,
) -> list[tuple[Path, str]]:
    """Write the model that ships and the labels to a new folder ``out``; with ``predictions``, per-timestep
    predictions of every log as Parquet; with ``mcap``, an MCAP file per log (the model's terrain and the labels, on
    the log's clock) in ``out/mcap``; with ``frames``, the camera frames of the labelled segments in ``out/frames``,
    a folder per terrain, and their index (``frames/index.csv``).

    The model that ships is the session's active classifier taught by what the session knows (``taught``, the
    default: ``cycle.shipped_version``, fitted once and kept beside the active version until the labels or the
    active version change); ``taught=False`` ships the active version as it is. ``say`` is told when that fit
    starts, after the target and the disk's room were checked.

    Returns:
        What was written, one (path, description) per item.
    """
    from training import load_bundle

    from ..cycle import shipped_version

    out = Path(out)
    check_target(out)  # before any work: a dangling link failed only at the rename, after the whole export
    _room_for_export(session, out, predictions=predictions or mcap)
    version, which = shipped_version(session, taught=taught, say=say)
    bundle = load_bundle(session.path / version.path)
    # written under a temporary name and renamed when whole: a refused export leaves no half-written folder
    try:
        with staged(out) as tmp:
            written = _write_export(
                session, tmp, version, bundle, which=which, predictions=predictions, mcap=mcap, frames=frames
            )
    except OSError as exc:  # a disk that filled while writing: one line, and no half-written folder
        raise WorkbenchError(f"{out}: cannot write the export ({exc.strerror or exc}); nothing was written") from None
    return [(out / path.relative_to(tmp), what) for path, what in written]


def _room_for_export(session: Session, out: Path, *, predictions: bool) -> None:
    """Refuse an export the disk holding ``out`` has no room for, before the work: the active version's files
    twice (the bundle and the taught one fitted for it), 4 MB for the ONNX file and the labels, and with
    predictions 8 bytes per step and column of every log."""
    from sessions import check_room, folder_bytes

    active = session.active_model("classifier")
    need = 4 << 20
    if active is not None:
        need += 2 * folder_bytes(session.path / active.path)
        if predictions:
            columns = len(active.metrics.get("per_class_recall") or {}) + 4
            need += 8 * columns * sum(x.n_samples for x in session.logs())
    check_room(out.parent, need, what="the export")


def _write_export(
    session: Session,
    out: Path,
    version: ModelVersion,
    bundle: ModelBundle,
    *,
    which: str,
    predictions: bool,
    mcap: bool,
    frames: bool,
) -> list[tuple[Path, str]]:
    from training import check_onnx, export_onnx

    from ..cycle import FigureTally, checks_summary, model_logs, signal_change_points

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
    paths = TerrainMap(session, logs)  # where each terrain was: the paths of the logs with positions
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
        for log, s in _scored(session, logs, out / ".scoring", version):
            if s.probs is not None:
                tally.add(log.id, s.probs)
                paths.add(log, s.probs, bundle.classes)
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
                streamed.append(_write_mcap(session, mcap_paths[log.id], log, version, bundle, s, paths.drawn(log)))
        if table is not None:
            empty = prediction_frame("", np.zeros((0, len(bundle.classes)), np.float32), bundle.classes, 1.0)
            table.close(with_drift_column(empty, bundle.drift is not None))
            streamed.insert(0, (table.path, "per-timestep predictions"))
    agreement = agree / agree_steps if unlabelled and agree_steps else None
    picture = paths.write(out / "bundle" / MAP_FILE)
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
        which=_taught_words(which),
        terrain_map=None if picture is None else f"![where each terrain was]({MAP_FILE})\n\n{paths.words()}",
    )
    (out / "bundle" / "MODEL_CARD.md").write_text(card)
    write_checks(out / "bundle", checks, names={x.id: x.name for x in logs})
    written.append((out / "bundle", f"model bundle {which} (safetensors + model.json + MODEL_CARD.md)"))
    if picture is not None:
        written.append((picture, f"the paths coloured by terrain ({paths.words()})"))
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


def _scored(
    session: Session, logs: list[LogInfo], folder: Path, version: ModelVersion
) -> Iterator[tuple[LogInfo, labeling.LogScores]]:
    """Every log with ``version``'s scores (the model that ships), in order: hours of logs in a forked process per
    core where there are more than two (``cycle.scored_in_processes``, the batches' arrays in ``folder``, removed at
    the end), else a group at a time here."""
    from .. import cycle

    processes = cycle.scoring_processes(logs, min_cores=EXPORT_MIN_CORES)
    if processes <= 1:
        yield from scored_logs(logs, lambda ids: cycle.score_session(session, ids, version=version))
        return
    folder.mkdir()
    try:
        steps = predictions_stream.GROUP_STEPS
        score = partial(_session_scores, version=version)
        yield from cycle.scored_in_processes(
            session, logs, score, processes=processes, folder=folder, group_steps=steps
        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _session_scores(session: Session, *, log_ids: list[int], version: ModelVersion, **_: object) -> SessionScores:
    """``cycle.score_session`` (the shipped version's scores, as the export writes them) in a forked child."""
    from .. import cycle

    return cycle.SessionScores(scores=cycle.score_session(session, list(log_ids), version=version))


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
    session: Session,
    path: Path,
    log: LogInfo,
    version: ModelVersion,
    bundle: ModelBundle,
    s: labeling.LogScores,
    drawn: TerrainPath | None,
) -> tuple[Path, str]:
    """One log's MCAP file: its terrain per sample, its labels and its path coloured by terrain, on the log's own
    clock."""
    write_terrain_mcap(
        path,
        LogClock.of(log),
        predictions=TerrainPredictions(tuple(bundle.classes), s.probs, s.drift),
        labels=session.segments(log.id),
        about={"model_version": str(version.id), "session": session.path.name, "source_file": log.source_path},
        path_drawn=drawn,
    )
    topics = ", ".join([PREDICTION_TOPIC, LABEL_TOPIC, *path_topics(drawn)])
    return path, f"{log.name}: topics {topics} on the log's clock"


def _taught_words(which: str) -> str:
    """``shipped_version``'s line as the card says it: a taught version says what teaching means."""
    if "taught by the session" not in which:
        return which
    return (
        f"{which}: stage 2 fitted from scratch on every label and, over each unlabelled stretch, the terrain the "
        "session was sure of there (its labels' votes and the model together, as the page showed them), so what "
        "the session learned of its runs ships to the robot"
    )
