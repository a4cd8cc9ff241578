"""CLI commands for label files: ``workbench labels export`` and ``workbench labels import``."""

from __future__ import annotations

import getpass
from pathlib import Path
from typing import Literal

import tyro

from sessions import LABEL_TOPIC, LogClock, Session, WorkbenchError

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
            for path, log in s.export_labels_mcap(out):
                n, span = len(s.segments(log.id)), LogClock.of(log).span()
                print(f"wrote {shown(path)}: {shown(log.name)}, topic {LABEL_TOPIC}, {n} segment(s), {span}")
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
            added = s.import_labels(file, author=author or getpass.getuser(), create_terrains=create_terrains)
            print(f"imported {len(added)} segment(s) from {shown(file)}")
        new = [t.name for t in s.terrains() if t.name not in before]
        if new:
            print(f"added terrain(s): {', '.join(shown(t) for t in new)}")
