"""Label save, click → committed: ``SharedState.add_label`` (what the UI's Save / A key calls) on a session whose
background worker is live, each label durable (SQLite WAL, ``synchronous = FULL``) when the call returns.

Reference beside it: a bare SQLite ``INSERT`` + ``COMMIT`` with the same durability on the same disk: the floor of
any durable save here. Correctness beside it: every saved label is in the session afterwards, nothing else.
"""

from __future__ import annotations

import sqlite3
import tempfile
import time
from pathlib import Path

import numpy as np
from speed_common import Row, fmt_s, parse_args, record

from sessions import Session
from workbench.demo import generate_walk, write_walk
from workbench.ui import SharedState


def bare_commits(folder: Path, n: int) -> np.ndarray:
    conn = sqlite3.connect(folder / "bare.sqlite", isolation_level=None)
    conn.execute("PRAGMA journal_mode = WAL")
    conn.execute("PRAGMA synchronous = FULL")
    conn.execute("CREATE TABLE seg (id INTEGER PRIMARY KEY, log INT, a INT, b INT, terrain TEXT)")
    out = np.empty(n)
    for i in range(n):
        t = time.perf_counter()
        conn.execute("BEGIN IMMEDIATE")
        conn.execute("INSERT INTO seg (log, a, b, terrain) VALUES (1, ?, ?, 'grass')", (i * 200, i * 200 + 100))
        conn.execute("COMMIT")
        out[i] = time.perf_counter() - t
    conn.close()
    return out


def main() -> None:
    args = parse_args(__doc__)
    n = 100 if args.quick else 1000
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        log_path = write_walk(generate_walk(0, n * 2.0 + 10.0), folder / "walk.mcap")
        session = Session.create(folder / "session")
        (log,) = session.ingest([log_path])
        terrains = ("grass", "gravel", "sand")
        for name in set(terrains) - {t.name for t in session.terrains()}:
            session.add_terrain(name)
        state = SharedState(session)
        times = np.empty(n)
        for i in range(n):
            a = i * 200  # 2 s apart at 100 Hz, 1 s long: never merged
            t = time.perf_counter()
            state.add_label(log.id, a, a + 100, terrains[i % 3], author="bench", source="manual")
            times[i] = time.perf_counter() - t
        kept = session.segments(log.id)
        in_order = sorted(kept, key=lambda s: s.start)
        ok = len(kept) == n and all(s.terrain == terrains[i % 3] for i, s in enumerate(in_order))
        state.stop()
        bare = bare_commits(folder, n)
    p50, p99, b99 = np.median(times), np.percentile(times, 99), np.percentile(bare, 99)
    row = Row(
        f"label save, click → committed ({n} labels, p50 / p99)",
        f"{fmt_s(p50)} / {fmt_s(p99)}",
        f"bare SQLite insert + durable commit: {fmt_s(np.median(bare))} / {fmt_s(b99)}",
        f"{p99 / b99:.1f}× the bare commit's p99",
        "≤ 50 ms p99",
        bool(p99 <= 0.05),
        f"{len(kept)} of {n} labels in the session after, terrains {'right' if ok else '**wrong**'}",
    )
    record("labels", [row], device=args.device)


if __name__ == "__main__":
    main()
