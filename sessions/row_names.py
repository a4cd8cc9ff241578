"""A label file's terrain names read as of when the file was written, where its rows say when that was.

A terrain keeps its identity through renames (``terrain_rows.names_since``); a name does not: after ``rename
concrete asphalt`` and a new ``concrete``, a ``concrete`` written before the rename is asphalt. Two kinds of row
say when they were written: a ``workbench suggest`` row names the classifier version it was drawn for, and a row
of the session's own export carries its segment's ``created_at`` (that segment, on that span of that log, is the
label the row is). Every other row is read by today's names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .check_rows import CHECK_COLUMNS, classifier_versions, given, version_number
from .terrain_rows import names_since

if TYPE_CHECKING:
    import pandas as pd

EXPORT_COLUMNS = {"created_at", "start_sample", "end_sample"}  # what ties a row of an export to its segment


def names_as_written(conn, frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with each row's terrain as the session names that terrain now, where the row says which it was.

    A row of an export whose segment is still there (same log, span and ``created_at``) and names a name that
    segment's terrain has held is that terrain; a filled-in ``suggest`` row reads its terrain by the names of its
    classifier version's moment, as its guess is read. The frame is returned as given when no row changes.
    """
    if "terrain" not in frame.columns:
        return frame
    out = frame["terrain"].astype(object).copy()
    exported = set(frame.columns) >= EXPORT_COLUMNS and "log" in frame.columns
    suggested = set(frame.columns) >= CHECK_COLUMNS
    versions = classifier_versions(conn) if suggested else {}
    held = _names_held(conn) if exported else {}
    moments: dict[int, dict[str, str]] = {}
    for index in frame.index:
        name = frame.at[index, "terrain"]
        if not given(name):
            continue
        name = str(name)
        terrain = _exported_terrain(conn, frame, index) if exported else None
        if terrain is not None and name in held.get(terrain[0], ()):
            out.at[index] = terrain[1]
            continue
        if suggested and (number := version_number(frame.at[index, "classifier"])) in versions:
            if number not in moments:
                moments[number] = names_since(conn, versions[number])
            out.at[index] = moments[number].get(name, name)
    if out.equals(frame["terrain"].astype(object)):
        return frame
    frame = frame.copy()
    frame["terrain"] = out
    return frame


def _names_held(conn) -> dict[int, set[str]]:
    """Every name each terrain has had: its name now and both sides of each rename."""
    held = {int(i): {str(n)} for i, n in conn.execute("SELECT id, name FROM terrains")}
    for terrain_id, old, new in conn.execute("SELECT terrain_id, old, new FROM terrain_renames"):
        held.setdefault(int(terrain_id), set()).update((str(old), str(new)))
    return held


def _exported_terrain(conn, frame: pd.DataFrame, index) -> tuple[int, str] | None:
    """The terrain (id, name now) of the segment a row of an export is, if it is still in the session."""
    cells = [frame.at[index, c] for c in ("log", "start_sample", "end_sample", "created_at")]
    if not all(given(c) for c in cells):
        return None
    try:
        start, stop = int(float(cells[1])), int(float(cells[2]))
    except (TypeError, ValueError, OverflowError):
        return None  # the row's own parse names the bad cell
    row = conn.execute(
        "SELECT t.id, t.name FROM segments s JOIN logs l ON l.id = s.log_id JOIN terrains t ON t.id = s.terrain_id "
        "WHERE l.name = ? AND s.start = ? AND s.stop = ? AND s.created_at = ?",
        (str(cells[0]), start, stop, str(cells[3])),
    ).fetchone()
    return None if row is None else (int(row[0]), str(row[1]))
