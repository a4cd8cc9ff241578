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


def labels_import(session: Pos[Path], file: Pos[Path], author: str = "") -> None:
    """Import a label file: every row, or nothing when any row names an unknown log or terrain.

    Args:
        session: The session folder.
        file: A .csv, .parquet or .json label file.
        author: Author for rows that name none (default: your user name).
    """
    with Session.open(session) as s:
        added = s.import_labels(file, author=author or getpass.getuser())
        print(f"imported {len(added)} segment(s) from {file}")
