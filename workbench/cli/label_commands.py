"""CLI commands for label files: ``workbench labels export``, ``workbench labels import`` and ``workbench suggest`` (the
next segments to label, as a label file to fill in)."""

from __future__ import annotations

import getpass
from dataclasses import replace
from pathlib import Path
from typing import Literal

import tyro

from sessions import (
    LABEL_TOPIC,
    LabelImport,
    LogClock,
    Session,
    WorkbenchError,
    check_new_target,
    file_format,
    path_topics,
)

from .terminal import shown

Pos = tyro.conf.Positional


def labels_export(
    session: Pos[Path],
    out: Path,
    format: Literal["auto", "label-studio"] = "auto",
    url_prefix: str | None = None,
) -> None:
    """Write every label segment to a .csv, .parquet or .json file, to MCAP (.mcap: one file per labelled log, on
    the log's own clock, topic /terrain/labels), or to Label Studio's time-series import (--format label-studio).

    Args:
        session: The session folder.
        out: The label file to write; .mcap with several labelled logs gives each file the log's name before .mcap.
        format: auto (by the file's suffix) or label-studio: OUT (.json) holds one task per log with its labels as
            timeserieslabels regions in seconds on the log's clock; OUT-files/ beside it holds each log's signals
            as CSV and the project's labeling config (labeling-config.xml).
        url_prefix: Label Studio only: what goes before each CSV's name in a task (default:
            /data/local-files/?d=OUT-files/, Label Studio's local-files URL with its document root at OUT's folder).
    """
    if out.suffix.lower() != ".mcap":  # the MCAP names are per log, each checked before the first is written
        check_new_target(out)
    if format == "label-studio":
        if out.suffix.lower() != ".json":
            raise WorkbenchError(f"{out}: Label Studio's import is JSON: name the tasks file *.json")
        with Session.open(session) as s:
            written = s.export_label_studio(out, url_prefix=url_prefix)
            print(f"wrote {shown(out)}: {len(s.logs())} task(s), one per log, {len(s.segments())} labelled region(s)")
            print(f"wrote {shown(written[1])} and {len(written) - 2} CSV file(s) of the logs' signals beside it")
        return
    if url_prefix is not None:
        raise WorkbenchError("--url-prefix is for --format label-studio")
    with Session.open(session) as s:
        if out.suffix.lower() == ".mcap":
            from ..maps import TerrainMap

            drawing = TerrainMap(s, s.logs())  # each log's path coloured by its labels, where it has positions
            for path, log in s.export_labels_mcap(out, drawn=drawing.drawn):
                n, span = len(s.segments(log.id)), LogClock.of(log).span()
                topics = ", ".join([LABEL_TOPIC, *path_topics(drawing.drawn(log))])
                print(f"wrote {shown(path)}: {shown(log.name)}, topics {topics}, {n} segment(s), {span}")
            if not s.segments():
                print("no label segments yet: nothing written")
            return
        s.export_labels(out)
        print(f"wrote {len(s.segments())} segment(s) to {shown(out)}")


def labels_import(
    session: Pos[Path], file: Pos[Path], author: str = "", create_terrains: bool = False, reference: bool = False
) -> None:
    """Import a label file: every row, or nothing when any row names an unknown log or terrain.

    Args:
        session: The session folder.
        file: A .csv, .parquet or .json label file (columns log, terrain, start_s/end_s or start_sample/end_sample),
            or Label Studio's JSON export of a time-series project (its timeserieslabels regions; a task names its
            log by data.log or by its data file's name).
        author: Author for rows that name none (default: your user name).
        create_terrains: Add the terrains the file names that the session lacks (none when the file is refused).
        reference: Store the rows as reference truth for `workbench evaluate session`, kept apart from the labels
            (they never train a model); it replaces the reference of each log the file names.
    """
    with Session.open(session) as s:
        before = {t.name for t in s.terrains()}
        if reference:
            n = s.import_reference(file, create_terrains=create_terrains)
            print(f"imported {n} reference row(s) from {shown(file)} (evaluation only, never labels)")
        else:
            done = s.import_labels(file, author=author or getpass.getuser(), create_terrains=create_terrains)
            print(import_line(done, shown(file)))
        new = [t.name for t in s.terrains() if t.name not in before]
        if new:
            print(f"added terrain(s): {', '.join(shown(t) for t in new)}")


def import_line(done: LabelImport, file: str) -> str:
    """What a label import did, in one line: labels new and already there, checks new and already kept."""
    parts = [f"imported {done.rows} row(s) from {file}: {len(done.segments)} new label(s)"]
    if done.already:
        parts[0] += f", {done.already} already labelled so (nothing changed)"
    if done.checks or done.checks_already:
        again = f", {done.checks_already} checked before (counted once)" if done.checks_already else ""
        parts.append(f"{done.checks} new check(s) of the model{again}")
    if done.checks_unrecorded:
        parts.append(
            f"{done.checks_unrecorded} row(s) the session did not write as suggestions of that model: labels, not "
            "counted as checks"
        )
    if done.blank:
        parts.append(f"{len(done.blank)} row(s) with no terrain left out (not labelled yet)")
    return "; ".join(parts)


def suggest(
    session: Pos[Path],
    out: Path,
    n: int | None = None,
    strategy: Literal["combined", "random", "entropy", "margin", "disagreement", "surprise"] = "combined",
    verify: bool = False,
    width: float = 10.0,
) -> None:
    """Write the next segments to label, the page's suggestion queue, as a label file whose terrain column is empty.

    With ``--verify``, the verification checks instead: uniform pieces of the time nobody labelled, stratified by
    log, as many as bring the session's 90 % interval to ``--width`` points (the page's Verify). After a Retrain the
    earlier checks tested an older model; these test the active one, and the session's figure rests on them.

    Fill in the terrain of the rows you label (leave the others empty) and `workbench labels import SESSION OUT`
    takes them as labels, each also a check of the model that suggested it, as a label made in the page is; then
    `workbench train SESSION --stage classifier` retrains. A script or another labelling tool drives the cycle so.

    Args:
        session: The session folder (trained: stage 1 at least; the guesses need a classifier).
        out: The file to write: .csv, .parquet or .json, with columns log, start_s, end_s (seconds from the log's
            start, as label files give them), terrain (empty), reason, guess, kind (suggestion, main answer or spot
            check) and classifier (the version that guessed).
        n: How many segments (default 12; with ``--verify``, as many as ``--width`` needs).
        strategy: How they are ranked (combined: the page's).
        verify: Uniform checks of the active classifier instead of ranked suggestions.
        width: With ``--verify``: the width, in points, the session's interval should come down to (10: ±5).
    """
    if n is not None and n < 1:
        raise WorkbenchError(f"--n {n}: ask for at least one segment")
    if not 0 < width < 100:
        raise WorkbenchError(f"--width {width:g}: a width in points, above 0 and under 100")
    file_format(out)
    check_new_target(out)  # before torch loads (seconds): a refused target is told at once
    import pandas as pd

    import labeling
    from sessions import write_frame

    from ..cycle import (
        SESSION_POLICY,
        answer_change,
        compute_scores,
        keep_answers,
        names_now,
        session_figures,
        signal_change_points,
        suggest_for_session,
        verification_queue,
    )

    with Session.open(session) as s:
        scores = compute_scores(s)
        if scores.predictor is None:
            raise WorkbenchError(f"{s.path}: no model yet; run `workbench train {s.path}` first")
        logs = [x for x in s.logs() if x.id in scores.scores]
        keep_answers(s, scores)
        asked = 0  # --verify: the checks asked for (--n, or as many as --width needs)
        if (change := answer_change(s, scores)) is not None:  # whether another round is worth it
            print(change.words())
        if verify:
            if scores.classifier is None:
                raise WorkbenchError(f"{s.path}: no classifier to verify; label two terrains and train it first")
            figure = session_figures(s, scores).session
            print(f"the session: {figure.words()}; {figure.plan_words(width=width / 100)}")
            asked = n if n is not None else min(figure.plan(width=width / 100), labeling.MOST_CHECKS)
            picks = verification_queue(s, scores, logs=logs, width=width / 100, n=n)
            if not picks:
                why = (
                    "no verification check is needed for that width"
                    if asked <= 0
                    else "the time nobody labelled holds no piece left to check (every unlabelled stretch is "
                    "labelled or checked already)"
                )
                print(f"nothing written: {why}")
                return
        else:
            points = {x.id: signal_change_points(s, x) for x in logs}
            policy = replace(SESSION_POLICY, strategy=strategy)
            picks = suggest_for_session(s, scores, points, logs=logs, n=n or 12, policy=policy)
        classes = names_now(s, scores)  # a guess names its terrain as the session does now
        rows = [
            (
                log.name,
                p.start / log.rate_hz,
                p.stop / log.rate_hz,
                "",
                p.reason,
                None if p.guess is None else classes[p.guess],
                p.kind,
                scores.classifier,
            )
            for log, p in picks
        ]
        if scores.classifier is not None:  # what a filled-in row checks: this kind, this guess (not the file's word)
            s.record_issued(
                [
                    (log.id, p.start, p.stop, scores.classifier, p.kind, None if p.guess is None else classes[p.guess])
                    for log, p in picks
                ]
            )
    columns = ["log", "start_s", "end_s", "terrain", "reason", "guess", "kind", "classifier"]
    frame = pd.DataFrame(rows, columns=columns).astype({"terrain": "string", "guess": "string"})
    write_frame(frame, out)
    print(f"wrote {len(rows)} segment(s) to {shown(out)}: fill in their terrain, then `workbench labels import`")
    if verify and len(rows) < asked:
        print(
            f"asked for {asked:,}: the time nobody labelled holds {len(rows)} more piece(s) to check (none "
            "overlapping another, a label or a check)"
        )
    if not verify and len(rows) < (n or 12):
        print(
            f"asked for {n or 12:,}: the session holds {len(rows)} piece(s) to suggest (unlabelled pieces cut at "
            "change points, none overlapping another or a label)"
        )
