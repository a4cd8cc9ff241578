"""``workbench ARGS`` with its own peak memory written to a file at exit: ``python cli_peak.py OUT ARGS...``.

A child's peak as ``wait4`` reports it includes its parent's at the fork (Linux keeps the larger hiwater mark across
``exec``), so a test process of 1.2 GB saw every child at 1.2 GB. ``VmHWM`` is the child's own address space's.
"""

from __future__ import annotations

import atexit
import sys
from pathlib import Path


def _report(out: Path) -> None:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            out.write_text(line.split()[1])  # kB


if __name__ == "__main__":
    atexit.register(_report, Path(sys.argv[1]))
    from workbench.cli import main

    sys.exit(main(sys.argv[2:]))
