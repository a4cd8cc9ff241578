"""Which log a label file's row names: by its ``log`` name, and by its ``source_file`` where the file gives one, so
that a row lands on the run it names (two logs of one name, a log renamed at ingest)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from .errors import LabelError
from .logs import LogInfo


def row_log(
    by_name: Mapping[str, list[LogInfo]],
    by_source: Mapping[str, list[LogInfo]],
    name: str,
    source: str | None,
    *,
    path: Path,
    where: str,
) -> LogInfo:
    """The one log a row names: by its ``log`` name, and by its ``source_file`` where the file gives one (a name
    two logs share in a session made before names were kept unique, or a log renamed at ingest: ``read_as``).
    ``by_name`` and ``by_source``: the session's logs by name and by source path (:func:`logs_by`).

    Raises:
        LabelError: No log has that name; the name is two logs' and no ``source_file`` tells which; the name and
            ``source_file`` name two different logs.
    """
    named = by_name.get(name, [])
    if source is not None:
        from_source = by_source.get(source, [])
        both = [x for x in from_source if x in named or x.info.get("read_as") == name]
        if len(both) == 1:
            return both[0]
        if named and from_source and not both:
            raise LabelError(
                f"{path}: {where}: log {name!r} is from {named[0].source_path}, but source_file says {source} "
                f"(log {from_source[0].name!r}); correct one of them; nothing was imported"
            )
    if len(named) == 1:
        return named[0]
    if not named:
        raise LabelError(f"{path}: {where}: unknown log {name!r}; nothing was imported")
    raise LabelError(
        f"{path}: {where}: log {name!r} names {len(named)} logs of the session (from "
        f"{', '.join(x.source_path for x in named)}); give the row's source_file to say which; nothing was imported"
    )


def logs_by(logs: list[LogInfo]) -> tuple[dict[str, list[LogInfo]], dict[str, list[LogInfo]]]:
    """The logs by name and by source path, for :func:`row_log`."""
    by_name: dict[str, list[LogInfo]] = {}
    by_source: dict[str, list[LogInfo]] = {}
    for x in logs:
        by_name.setdefault(x.name, []).append(x)
        by_source.setdefault(x.source_path, []).append(x)
    return by_name, by_source
