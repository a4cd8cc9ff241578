"""A row of a ``workbench suggest`` file filled in is a check of the classifier that guessed there: its fields are
read here, strictly (a version the session has, a kind of check it knows), and compared by terrain, not by name."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .checks import CHECK_KINDS, insert_check, issued_check
from .errors import LabelError
from .terrain_rows import names_since

if TYPE_CHECKING:
    import pandas as pd

    from .label_files import Row


CHECK_COLUMNS = {"guess", "kind", "classifier"}  # the columns of a suggestion file that make its rows checks


def classifier_versions(conn) -> dict[int, str]:
    """The session's classifier versions: id to when it was made."""
    rows = conn.execute("SELECT id, created_at FROM model_versions WHERE stage = 'classifier'")
    return {int(i): str(at) for i, at in rows}


def check_of_row(conn, cells: pd.Series, row: Row, versions: dict[int, str], *, author: str, counts: list[int]) -> None:
    """The check a filled-in row of a suggestion file is: the classifier's guess against the person's terrain (its
    guess over the piece, so agreement is 1 or 0), compared by terrain rather than by name (a terrain renamed since
    the file was written is the same terrain). The kind and the guess are the ones the session wrote for that
    piece (``issued``), never the file's own: a row whose piece the session did not write is a label and no check.
    ``counts`` gains the check: ``[new, already kept, not written by the session]``.

    Raises:
        LabelError: The row names a classifier version the session does not have, or a kind it does not know, or
            its kind or guess is not what the session wrote for that piece.
    """
    guess, kind, version = cells["guess"], cells["kind"], cells["classifier"]
    if not given(guess):
        return  # a row the classifier had no guess for (no classifier yet): no check
    if not given(version):  # a guess is a classifier's: without its version nothing says which model was tested
        raise LabelError(f"the guess {str(guess)!r} names no classifier version (the classifier column is empty)")
    if str(kind) not in CHECK_KINDS:
        raise LabelError(f"kind {str(kind)!r} is not a kind of check; one of {', '.join(CHECK_KINDS)}")
    number = version_number(version)
    if number is None or number not in versions:
        known = f"it has {_span(sorted(versions))}" if versions else "it has none"
        raise LabelError(f"classifier {str(version)!r} is not a classifier version of this session ({known})")
    issued = issued_check(conn, row.log.id, row.start, row.stop, number)
    if issued is None:  # the file's columns alone would let a row vouch for the model: a label, no check
        counts[2] += 1
        return
    names = names_since(conn, versions[number])
    if str(kind) != issued[0]:
        raise LabelError(f"kind {str(kind)!r} is not what the session drew for this piece ({issued[0]!r})")
    predicted = names.get(str(guess), str(guess))
    said = None if issued[1] is None else names.get(issued[1], issued[1])
    if predicted != said:
        raise LabelError(
            f"guess {str(guess)!r} is not the answer classifier v{number} gave for this piece ({issued[1]!r}, as "
            "the session wrote it)"
        )
    kind = issued[0]
    _, new = insert_check(
        conn,
        row.log.id,
        row.start,
        row.stop,
        row.terrain,
        predicted=predicted,
        agreement=float(predicted == row.terrain),
        classifier=number,
        kind=str(kind),
        author=author,
    )
    counts[0 if new else 1] += 1


def version_number(value: object) -> int | None:
    """A version number from a cell: a whole number written as one (``7``, ``"7"``, ``7.0`` from a column with empty
    cells), else ``None`` (``true``, ``2.7``, ``nan``, ``1e400``, ``abc``)."""
    if isinstance(value, bool | np.bool_):
        return None
    if isinstance(value, int | np.integer):
        return int(value)
    try:
        x = float(str(value).strip())
    except ValueError:
        return None
    return int(x) if math.isfinite(x) and x.is_integer() and 0 < x < 2**62 else None


def _span(ids: list[int]) -> str:
    """Version numbers as a reader takes them in: ``v1``, ``v1 to v9``."""
    return f"v{ids[0]}" if len(ids) == 1 else f"v{ids[0]} to v{ids[-1]}"


def given(value: object) -> bool:
    """Whether a cell holds anything: CSV cells are read as text (empty: ""), Parquet and JSON ones may be null."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return False
    return not (isinstance(value, str) and not value.strip())
