"""CLI commands for label files: ``workbench labels export`` and ``workbench labels import``."""

from __future__ import annotations

import getpass
from pathlib import Path

import tyro

from sessions import Session

Pos = tyro.conf.Positional


def labels_export(session: Pos[Path], out: Path) -> None:
    """Write every label segment to a .csv, .parquet or .json file.

    Args:
        session: The session folder.
        out: The label file to write.
    """
    with Session.open(session) as s:
        s.export_labels(out)
        print(f"wrote {len(s.segments())} segment(s) to {out}")


def labels_import(
    session: Pos[Path], file: Pos[Path], author: str = "", create_terrains: bool = False, reference: bool = False
) -> None:
    """Import a label file: every row, or nothing when any row names an unknown log or terrain.

    Args:
        session: The session folder.
        file: A .csv, .parquet or .json label file (columns log, terrain, start_s/end_s or start_sample/end_sample).
        author: Author for rows that name none (default: your user name).
        create_terrains: Add the terrains the file names that the session lacks (none when the file is refused).
        reference: Store the rows as reference truth for `workbench evaluate session`, kept apart from the labels
            (they never train a model); it replaces the reference of each log the file names.
    """
    with Session.open(session) as s:
        before = {t.name for t in s.terrains()}
        if reference:
            n = s.import_reference(file, create_terrains=create_terrains)
            print(f"imported {n} reference row(s) from {file} (evaluation only, never labels)")
        else:
            added = s.import_labels(file, author=author or getpass.getuser(), create_terrains=create_terrains)
            print(f"imported {len(added)} segment(s) from {file}")
        new = [t.name for t in s.terrains() if t.name not in before]
        if new:
            print(f"added terrain(s): {', '.join(new)}")
