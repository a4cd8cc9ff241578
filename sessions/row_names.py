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
    exported = set(frame.columns) >= EXPORT_COLUMNS and "log" in frame.columns
    suggested = set(frame.columns) >= CHECK_COLUMNS
    if not (exported or suggested):  # nothing says when the file was written: today's names
        return frame
    segments = _segments_by_row(conn) if exported else {}
    held = _names_held(conn) if exported else {}
    versions = classifier_versions(conn) if suggested else {}
    moments: dict[int, dict[str, str]] = {}
    names = list(frame["terrain"])
    at = _exported_keys(frame) if exported else [None] * len(frame)
    drawn = list(frame["classifier"]) if suggested else [None] * len(frame)
    out, changed = list(names), False
    for j, (name, key, version) in enumerate(zip(names, at, drawn, strict=True)):
        if not given(name):
            continue
        name = str(name)
        terrain = segments.get(key) if key is not None else None
        if terrain is not None and name in held.get(terrain[0], ()):
            out[j] = terrain[1]
        elif suggested and (number := version_number(version)) in versions:
            if number not in moments:
                moments[number] = names_since(conn, versions[number])
            out[j] = moments[number].get(name, name)
        changed = changed or out[j] != name
    if not changed:
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


def _segments_by_row(conn) -> dict[tuple[str, int, int, str], tuple[int, str]]:
    """Every segment by what an export's row of it holds (log name, start, stop, created_at): its terrain (id, name
    now)."""
    rows = conn.execute(
        "SELECT l.name, s.start, s.stop, s.created_at, t.id, t.name FROM segments s JOIN logs l ON l.id = s.log_id "
        "JOIN terrains t ON t.id = s.terrain_id"
    )
    return {(str(a), int(b), int(c), str(d)): (int(e), str(f)) for a, b, c, d, e, f in rows}


def _exported_keys(frame: pd.DataFrame) -> list[tuple[str, int, int, str] | None]:
    """Each row's (log, start, stop, created_at) as an export writes them, ``None`` where a cell is not one."""
    out: list[tuple[str, int, int, str] | None] = []
    cells = zip(frame["log"], frame["start_sample"], frame["end_sample"], frame["created_at"], strict=True)
    for log, a, b, made in cells:
        try:
            ok = given(log) and given(made) and float(a).is_integer() and float(b).is_integer()
            out.append((str(log), int(float(a)), int(float(b)), str(made)) if ok else None)
        except (TypeError, ValueError, OverflowError):
            out.append(None)  # the row's own parse names the bad cell
    return out
