"""``workbench ingest --dry-run``: what would be read, written as a mapping file a user can edit and pass back."""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from pathlib import Path

from sessions import (
    DiscardRows,
    IngestError,
    IngestOptions,
    Mapping,
    TimeColumn,
    align,
    plan_sources,
    read_source,
    sniff_csv,
)

from .terminal import shown


def _toml_str(text: str) -> str:
    """A TOML basic string: quotes, backslashes and every control or format character escaped, so a topic named
    ``"/imu\\nrate_hz = 3.0"`` stays one string (JSON's escaping left DEL and C1 controls raw, which TOML refuses)."""
    out = []
    for ch in text:
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ch.isprintable() or ch == " ":
            out.append(ch)
        else:
            code = ord(ch)
            out.append(f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}")
    return '"' + "".join(out) + '"'


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return _toml_str(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)


def _csv_section(
    mapping: Mapping, sniffed: tuple[bool, int] | None, no_time: bool, found: TimeColumn | None
) -> list[str]:
    """The ``[csv]`` table: what the mapping given says, what the first generic CSV looked like (its time column
    when the reader found it, said outright so the mapping ingests as is), and, when it has no time column, the two
    ways to say how it is timed (commented out: the user picks one)."""
    keys: dict[str, object] = {}
    if sniffed is not None and mapping.header is None and not sniffed[0]:
        keys["header"] = False  # said outright, so the file reads the same when detection would guess otherwise
    for key in ("header", "columns", "time_column", "time_unit", "sample_rate_hz"):
        value = getattr(mapping, key)
        if value not in (None, ()):
            keys[key] = list(value) if isinstance(value, tuple) else value
    lines = []
    if found is not None and mapping.time_column is None:
        headerless = keys.get("header") is False and not mapping.columns
        keys["time_column"] = found.index if headerless else found.name
        keys.setdefault("time_unit", found.unit)
        lines.append(f"# time: {found.describe()}, found by its steady steps")
    lines += [f"{k} = {_toml_value(v)}" for k, v in keys.items()]
    if no_time:
        lines += [
            "# the first column is no time: uncomment one of these two lines",
            "# time_column = 0          # the column holding time, by 0-based index or by name",
            "# sample_rate_hz = 100.0   # or: rows evenly sampled at this rate, no time column",
        ]
    return ["[csv]", *lines, ""] if lines else []


def dry_run_report(files: Sequence[Path], options: IngestOptions) -> tuple[bool, str]:
    """Read and align every source without writing anything.

    Returns:
        Whether every file would be ingested, and the report: TOML whose comments describe each file and whose
        ``[[channels]]`` entries are the inferred mapping (save it, edit it, pass it with ``--mapping``).
    """
    ok = True
    lines: list[str] = [
        "# workbench ingest --dry-run: nothing was written.",
        "# Save this as mapping.toml, edit it, and pass it back with --mapping mapping.toml.",
    ]
    channel_lines: list[str] = []
    seen: set[tuple[str, str]] = set()
    sniffed: tuple[bool, int] | None = None  # the first generic CSV's header and width
    found: TimeColumn | None = None  # and its time column, when the reader found it
    first_csv = True
    no_time = False
    tf_children: set[str] = set()  # the /tf child frames a path was read from
    odometry: list[str] = []  # odometry topics not read as signals: their velocities are offered
    sources, errors = plan_sources(list(files))
    for err in errors:
        ok = False
        lines.append(f"# REFUSED {err}")
    for source in sources:
        lines.append("#")
        lines.append(f"# {', '.join(str(f) for f in source.files)}  [{source.format}]")
        if source.format == "csv" and sniffed is None:
            with contextlib.suppress(OSError, UnicodeDecodeError):  # read_source below says what is wrong
                sniffed = sniff_csv(source.files[0])
        try:
            parsed_logs, reports = read_source(source, options)
            aligned = [align(p, options, allocate=DiscardRows) for p in parsed_logs]
        except IngestError as err:
            ok = False
            no_time = no_time or (source.format == "csv" and err.reason.startswith("no time column"))
            first_csv = first_csv and source.format != "csv"
            lines.append(f"#   REFUSED: {err.reason}" + (f" ({err.where})" if err.where else ""))
            continue
        if source.format == "csv" and first_csv:
            found, first_csv = parsed_logs[0].found_time, False
        for report in reports:
            if report.unusable and report.schema.replace("/msg/", "/") == "nav_msgs/Odometry":
                odometry.append(report.topic)
            if report.unusable:
                lines.append(
                    f"#   topic {report.topic} ({report.schema}, {report.messages} msgs): not used: {report.unusable}"
                )
            elif report.note:
                lines.append(f"#   topic {report.topic} ({report.schema}, {report.messages} msgs): {report.note}")
            else:
                lines.append(
                    f"#   topic {report.topic} ({report.schema}, {report.messages} msgs): {len(report.channels)} fields"
                )
        for log in aligned:
            rates = ", ".join(
                f"{k} {v:.1f} Hz" + (f" ({log.repeats[k]} repeated samples dropped)" if log.repeats.get(k) else "")
                for k, v in log.stream_rates.items()
            )
            lines.append(
                f"#   -> log {log.parsed.name!r}: {log.data.shape[0]} samples at {log.rate_hz:g} Hz "
                f"({log.data.shape[0] / log.rate_hz:.1f} s), {len(log.channels)} channels, {len(log.gaps)} gaps; "
                f"streams: {rates}"
            )
            for note in log.parsed.notes:
                lines.append(f"#      note: {note}")
            for track in log.parsed.poses:
                lines.append(
                    f"#      position: {track.source} ({track.kind}, frame {track.frame}, {len(track.times):,} poses"
                    + (f", {track.dropped:,} dropped" if track.dropped else "")
                    + "): the robot's path, never a signal"
                )
                tf_children.update({track.source.partition(":")[2]} if track.kind == "tf" else set())
            if log.parsed.reference_terrain:
                lines.append(f"#      reference terrain (evaluation only): {log.parsed.reference_terrain}")
            for gap in log.gaps[:5]:
                lines.append(f"#      gap in {gap.stream}: samples {gap.start}-{gap.stop}: {gap.reason}")
            for ch in log.channels:
                src, _, field = ch.source.partition(":")
                key = (src if source.format in ("mcap", "bag") else field, ch.name)
                if key in seen:
                    continue
                seen.add(key)
                entry = ["[[channels]]", f"source = {_toml_str(key[0])}"]
                if source.format in ("mcap", "bag"):
                    entry.append(f"field = {_toml_str(field)}")
                entry += [f"name = {_toml_str(ch.name)}", f"unit = {_toml_str(ch.unit)}", ""]
                channel_lines.extend(entry)
    lines.append("")
    if options.target_rate:
        lines.append(f"rate_hz = {options.target_rate}")
    if options.mapping.ignore:
        lines.append(f"ignore = {_toml_value(list(options.mapping.ignore))}")
    lines.append("")
    lines += _csv_section(options.mapping, sniffed, no_time, found)
    lines += _pose_section(options.mapping, tf_children, odometry)
    # a comment holds names from the files (topics, logs, notes): a newline in one would end the comment
    lines = ["#" + shown(line[1:]) if line.startswith("#") else line for line in lines]
    return ok, "\n".join(lines + channel_lines)


def _pose_section(mapping, tf_children: set[str], odometry: list[str]) -> list[str]:
    """The mapping's ``[poses]`` choice where ``/tf`` gave a path, and each odometry topic's velocities offered as
    signals (commented: a robot whose only topics are its odometry and poses has no other)."""
    lines = []
    if tf_children or mapping.tf_child:
        child = mapping.tf_child or sorted(tf_children)[0]
        lines += ["# the /tf child frame the robot's path follows (its base by default)", "[poses]"]
        lines += [f"tf_child = {_toml_str(child)}", ""]
    for topic in odometry:
        lines.append(f"# {topic}'s velocities as signals (uncomment where the log has no IMU or other sensor):")
        for axis in ("linear.x", "linear.y", "angular.z"):
            lines += ["# [[channels]]", f"# source = {_toml_str(topic)}", f'# field = "twist.twist.{axis}"', "#"]
        lines.append("")
    return lines
