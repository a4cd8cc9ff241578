"""Ingests the files named on stdin into one session, one JSON line per file: what a hostile corpus is fed through.

Run by ``test_hostile_input`` as a separate process so that a hang can be cut off per file and the peak memory read.
"""

from __future__ import annotations

import json
import sys
import time
import traceback
from pathlib import Path

from sessions import Session, WorkbenchError


def own_peak_kb() -> int:
    """This process's own peak RSS (``VmHWM``): ``ru_maxrss`` keeps the parent's at the fork across ``exec``, so
    a worker started by a test process of 1.8 GB read 1.8 GB before its first file (``cli_peak.py`` says more)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    return 0


def main() -> None:
    with Session.open(sys.argv[1]) as session:
        print(json.dumps({"ready": True}), flush=True)
        for line in sys.stdin:
            path = line.rstrip("\n")
            t = time.perf_counter()
            try:
                logs = session.ingest([path])
                out: dict = {"ok": True, "samples": sum(x.n_samples for x in logs)}
            except WorkbenchError as exc:
                out = {"ok": False, "error": str(exc)}
            except BaseException as exc:  # anything else is a defect: report it with its traceback
                out = {"ok": False, "crash": f"{type(exc).__name__}: {exc}", "trace": traceback.format_exc()}
            out["seconds"] = time.perf_counter() - t
            out["peak_mb"] = own_peak_kb() / 1024
            print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
