"""``workbench ingest --dry-run``: what would be read, written as a mapping file a user can edit and pass back."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from sessions import IngestError, IngestOptions, align, plan_sources, read_source


def _toml_str(text: str) -> str:
    return json.dumps(text, ensure_ascii=False)  # a JSON string is a valid TOML basic string


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
    sources, errors = plan_sources(list(files))
    for err in errors:
        ok = False
        lines.append(f"# REFUSED {err}")
    for source in sources:
        lines.append("#")
        lines.append(f"# {', '.join(str(f) for f in source.files)}  [{source.format}]")
        try:
            parsed_logs, reports = read_source(source, options)
            aligned = [align(p, options) for p in parsed_logs]
        except IngestError as err:
            ok = False
            lines.append(f"#   REFUSED: {err.reason}" + (f" ({err.where})" if err.where else ""))
            continue
        for report in reports:
            if report.unusable:
                lines.append(
                    f"#   topic {report.topic} ({report.schema}, {report.messages} msgs): not used: {report.unusable}"
                )
            else:
                lines.append(
                    f"#   topic {report.topic} ({report.schema}, {report.messages} msgs): {len(report.channels)} fields"
                )
        for log in aligned:
            rates = ", ".join(f"{k} {v:.1f} Hz" for k, v in log.stream_rates.items())
            lines.append(
                f"#   -> log {log.parsed.name!r}: {log.data.shape[0]} samples at {log.rate_hz:g} Hz "
                f"({log.data.shape[0] / log.rate_hz:.1f} s), {len(log.channels)} channels, {len(log.gaps)} gaps; "
                f"streams: {rates}"
            )
            if log.parsed.reference_terrain:
                lines.append(f"#      reference terrain (evaluation only): {log.parsed.reference_terrain}")
            for gap in log.gaps[:5]:
                lines.append(f"#      gap in {gap.stream}: samples {gap.start}-{gap.stop}: {gap.reason}")
            for ch in log.channels:
                src, _, field = ch.source.partition(":")
                key = (src if source.format == "mcap" else field, ch.name)
                if key in seen:
                    continue
                seen.add(key)
                entry = ["[[channels]]", f"source = {_toml_str(key[0])}"]
                if source.format == "mcap":
                    entry.append(f"field = {_toml_str(field)}")
                entry += [f"name = {_toml_str(ch.name)}", f"unit = {_toml_str(ch.unit)}", ""]
                channel_lines.extend(entry)
    lines.append("")
    if options.target_rate:
        lines.append(f"rate_hz = {options.target_rate}")
    return ok, "\n".join(lines + channel_lines)
