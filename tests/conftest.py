"""Shared fixtures: temporary sessions, a snapshot of a session's state, small generated logs, shared data."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path

import pytest

from sessions import Session

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("WORKBENCH_SHARED_DATA", REPO.parent / "shared" / "data"))


def shared_data(*parts: str) -> Path:
    """A path under ``../shared/data``; skips the test with the reason when it is absent (a user's clone)."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"shared data not available: {path} (tests that read ../shared/data/ skip without it)")
    return path


def snapshot(session_path: Path) -> tuple:
    """Everything a session holds: every table's rows and the files in its folder (names and sizes)."""
    conn = sqlite3.connect(f"file:{session_path / 'session.sqlite'}?mode=ro", uri=True)
    try:
        tables = [r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table' ORDER BY name")]
        rows = {t: conn.execute(f"SELECT * FROM {t} ORDER BY rowid").fetchall() for t in tables}
    finally:
        conn.close()
    files = sorted(
        (str(p.relative_to(session_path)), p.stat().st_size)
        for p in session_path.rglob("*")
        if p.is_file() and not p.name.startswith("session.sqlite")
    )
    return rows, files


@pytest.fixture
def session(tmp_path: Path) -> Session:
    s = Session.create(tmp_path / "session")
    yield s
    s.close()


@pytest.fixture(scope="session")
def demo_mcap(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 90 s demo walk as MCAP (with its .truth.json sidecar)."""
    from workbench.demo import generate_walk, write_walk

    out = tmp_path_factory.mktemp("demo") / "walk.mcap"
    return write_walk(generate_walk(3, 90.0), out, seed=3)
