"""Gather the rows every benchmark recorded into one Markdown table per device (``results/speed.md`` for the CPU,
``results/speed-<device>.md`` for another)."""

from __future__ import annotations

import json
import sys
import time

from speed_common import RAW_SPEED, RESULTS, Row, table


def main(device: str = "cpu") -> int:
    folder = RAW_SPEED / device
    files = sorted(folder.glob("*.json")) if folder.is_dir() else []
    if not files:
        print(f"no benchmark results in {folder}")
        return 1
    rows, meta = [], {}
    for f in files:
        data = json.loads(f.read_text())
        rows += [Row(**r) for r in data["rows"]]
        meta = data.get("meta", meta)
    head = (
        f"# Speed and memory: `make bench` on {device} ({meta.get('cpus', '?')} CPUs), {time.strftime('%Y-%m-%d')}\n\n"
        "Every figure beside a reference measured in the same run (rerun: `make bench`; `make bench DEVICE=cuda` on a "
        f"GPU);\neach benchmark's rows as JSON under `raw/speed/{device}/`. Below the table, what each session "
        "measured, and why.\n\n"
    )
    text = head + table(rows) + "\n"
    out = RESULTS / ("speed.md" if device == "cpu" else f"speed-{device}.md")
    print(text)
    if out.exists():  # the sections written by hand below the table (what each session measured, and why) stay
        old = out.read_text()
        at = old.find("\n## ")
        if at >= 0:
            text += old[at:]
    out.write_text(text)
    missed = [r.figure for r in rows if r.met is False]
    if missed:
        print("targets missed:\n" + "\n".join(f"- {m}" for m in missed))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(*sys.argv[1:2]))
