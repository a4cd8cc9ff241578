"""The terrains table's rows, added and removed inside a caller's transaction (the store's and the label import's)."""

from __future__ import annotations

from .errors import LabelError
from .limits import name_refusal
from .schema import KNOWN_TERRAIN_COLORS

NEW_TERRAIN_COLORS = ("#1e88e5", "#e53935", "#8e24aa", "#00897b", "#3949ab", "#d81b60", "#00acc1", "#7cb342")


def delete_terrain(conn, name: str) -> None:
    """Remove a terrain no segment uses, inside the caller's transaction."""
    row = conn.execute("SELECT id FROM terrains WHERE name = ?", (name,)).fetchone()
    if row is None:
        raise LabelError(f"unknown terrain {name!r}")
    used = conn.execute("SELECT COUNT(*) FROM segments WHERE terrain_id = ?", (row[0],)).fetchone()[0]
    if used:
        raise LabelError(f"terrain {name!r} labels {used} segment(s); relabel or delete them first")
    conn.execute("DELETE FROM terrains WHERE id = ?", (row[0],))


def insert_terrain(conn, name: str, color: str | None) -> None:
    """Add a terrain at the end of the list inside the caller's transaction (colour: the palette's next)."""
    if not name:
        raise LabelError("a terrain needs a name")
    if (why := name_refusal(name, "terrain")) is not None:
        raise LabelError(why)
    if conn.execute("SELECT 1 FROM terrains WHERE name = ?", (name,)).fetchone():
        raise LabelError(f"terrain {name!r} exists already")
    pos = conn.execute("SELECT COALESCE(MAX(position) + 1, 0) FROM terrains").fetchone()[0]
    if color is None:
        taken = {r[0] for r in conn.execute("SELECT color FROM terrains")}
        known = KNOWN_TERRAIN_COLORS.get(name.lower())
        color = (
            known
            if known is not None and known not in taken
            else next(
                (c for c in NEW_TERRAIN_COLORS if c not in taken), NEW_TERRAIN_COLORS[pos % len(NEW_TERRAIN_COLORS)]
            )
        )
    conn.execute("INSERT INTO terrains (name, color, position) VALUES (?, ?, ?)", (name, color, pos))


def rename_terrain_row(conn, old: str, new: str, *, at: str) -> None:
    """Rename a terrain inside the caller's transaction, keeping the rename (``terrain_renames``) so a name that a
    model, a check or a file used before it is found again; the checks and reference rows, which keep names, follow.

    Raises:
        LabelError: ``new`` is refused as a name or taken, or ``old`` is unknown.
    """
    if (why := name_refusal(new, "terrain")) is not None:
        raise LabelError(why)
    if not new or conn.execute("SELECT 1 FROM terrains WHERE name = ?", (new,)).fetchone():
        raise LabelError(f"cannot rename {old!r} to {new!r}: empty or taken")
    row = conn.execute("SELECT id FROM terrains WHERE name = ?", (old,)).fetchone()
    if row is None:
        raise LabelError(f"unknown terrain {old!r}")
    conn.execute("UPDATE terrains SET name = ? WHERE id = ?", (new, row[0]))
    conn.execute("INSERT INTO terrain_renames (terrain_id, old, new, at) VALUES (?, ?, ?, ?)", (row[0], old, new, at))
    for table, column in (("checks", "terrain"), ("checks", "predicted"), ("reference", "terrain")):
        conn.execute(f"UPDATE {table} SET {column} = ? WHERE {column} = ?", (new, old))


def names_since(conn, at: str) -> dict[str, str]:
    """Every name a terrain of the session has had since ``at`` (an ISO time stamp), to its name now.

    A model trained at ``at`` names its classes as they were called then, and a file written from it may use a later
    name: both are found. Where two terrains held one name in turn, the one that held it at ``at`` has it (after
    ``rename concrete asphalt`` and a new ``concrete``, a model's ``concrete`` is asphalt; a swap of two names
    through a third maps each back), then a name held in between, then the name a terrain has now.
    """
    now = {int(i): str(n) for i, n in conn.execute("SELECT id, name FROM terrains")}
    renames = [
        (int(t), str(old), str(new))
        for t, old, new in conn.execute(
            "SELECT terrain_id, old, new FROM terrain_renames WHERE at > ? ORDER BY at, id", (at,)
        ).fetchall()
        if int(t) in now
    ]
    out = {name: name for name in now.values()}
    for terrain_id, old, new in renames:  # the names held in between
        out[old] = out[new] = now[terrain_id]
    then: dict[int, str] = {}
    for terrain_id, old, _ in reversed(renames):  # a renamed terrain's name at `at`, the renames since undone
        then[terrain_id] = old
    # a name a renamed terrain held at `at` is its, whoever holds it now (a terrain that has it now took it later:
    # names are unique at every moment)
    out.update({name: now[terrain_id] for terrain_id, name in then.items()})
    return out


def renamed_to(conn) -> dict[str, str]:
    """A name no terrain has now, to the name now of the terrain that last gave it up (``dirt`` renamed ``soil``:
    ``{"dirt": "soil"}``): what a refusal of a file's old name says."""
    now = {int(i): str(n) for i, n in conn.execute("SELECT id, name FROM terrains")}
    out: dict[str, str] = {}
    for terrain_id, old in conn.execute("SELECT terrain_id, old FROM terrain_renames ORDER BY at, id"):
        if int(terrain_id) in now and str(old) not in now.values():
            out[str(old)] = now[int(terrain_id)]
    return out
