"""Session folders: create/open round trips, catalog, memory-mapped samples, schema versions and migrations."""

from __future__ import annotations

import os
import sqlite3
import threading
from pathlib import Path

import numpy as np
import pytest

from sessions import SCHEMA_VERSION, Session, SessionError
from sessions.ingest_lock import ingesting
from sessions.rowfiles import NpyWriter
from sessions.schema import MIGRATIONS, migrate, schema_version


def test_create_then_open_round_trip(tmp_path: Path, demo_mcap: Path) -> None:
    path = tmp_path / "s"
    with Session.create(path) as s:
        (log,) = s.ingest([demo_mcap])
        s.add_terrain("grass")
        seg = s.add_segment(log.id, 100, 400, "grass", author="ana")
        data = s.samples(log.id)
    with Session.open(path) as s:
        assert [x.name for x in s.logs()] == ["walk"]
        again = s.log(log.id)
        assert again == log
        assert s.segments() == [seg]
        np.testing.assert_array_equal(s.samples(log.id), data)
    assert (path / "session.sqlite").is_file()
    assert (path / log.file).is_file()
    conn = sqlite3.connect(path / "session.sqlite")
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION


def test_a_forked_child_reads_and_writes_through_a_connection_of_its_own(tmp_path: Path, demo_mcap: Path) -> None:
    """A process forked under the session's lock (``fork_guard``) gives itself a connection and locks
    (``after_fork``): it reads and writes the session while a thread of the parent held the lock at the fork, and
    the parent's connection, never closed by the child, still reads and writes after it ended."""
    with Session.create(tmp_path / "s") as s:
        (log,) = s.ingest([demo_mcap])
        s.add_terrain("grass")
        held, release = threading.Event(), threading.Event()

        def hold_the_camera_lock() -> None:  # a thread of the parent inside the camera index at the fork
            with s._camera_lock:
                held.set()
                release.wait(30)

        other = threading.Thread(target=hold_the_camera_lock)
        other.start()
        held.wait(30)
        with s.fork_guard():
            pid = os.fork()
            if pid == 0:
                code = 1
                try:
                    s.after_fork()
                    s.add_segment(log.id, 0, 100, "grass", author="child")
                    code = 0 if [x.name for x in s.logs()] == ["walk"] else 3
                    code = code if s._camera_lock.acquire(timeout=5) else 4  # its own, not the one held at the fork
                finally:
                    os._exit(code)
        release.set()
        other.join()
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0
        assert [g.author for g in s.segments()] == ["child"]  # the child's write, read through the parent's connection
        s.add_segment(log.id, 200, 300, "grass", author="parent")
    with Session.open(tmp_path / "s") as s:
        assert sorted(g.author for g in s.segments()) == ["child", "parent"]


def test_samples_reads_only_the_slice_it_is_asked(session: Session, demo_mcap: Path) -> None:
    (log,) = session.ingest([demo_mcap])
    whole = session.array(log.id)
    assert isinstance(whole, np.memmap)
    assert whole.shape == (log.n_samples, log.n_channels) and whole.dtype == np.float32
    part = session.samples(log.id, 1000, 1050)
    assert part.shape == (50, log.n_channels)
    np.testing.assert_array_equal(part, whole[1000:1050])
    with pytest.raises(ValueError):
        whole[0, 0] = 1.0  # read-only: nothing writes a log's array after ingest


def test_log_catalog_has_channels_units_and_rate(session: Session, demo_mcap: Path) -> None:
    (log,) = session.ingest([demo_mcap])
    assert log.rate_hz == pytest.approx(100.0, rel=1e-4)
    assert log.n_channels == 22
    units = {c.name: c.unit for c in log.channels}
    assert units["imu/angular_velocity.x"] == "rad/s"
    assert units["imu/linear_acceleration.z"] == "m/s²"
    assert units["fl/force.z"] == "N"
    assert all(c.source.startswith(("/imu:", "/feet/")) for c in log.channels)
    assert log.duration_s == pytest.approx(90.0, abs=0.1)


def test_create_refuses_existing_session_and_nonempty_folder(tmp_path: Path) -> None:
    Session.create(tmp_path / "s").close()
    with pytest.raises(SessionError, match="already a session"):
        Session.create(tmp_path / "s")
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "x.txt").write_text("x")
    with pytest.raises(SessionError, match="not an empty folder"):
        Session.create(tmp_path / "busy")


def test_open_refuses_a_folder_that_is_not_a_session(tmp_path: Path) -> None:
    with pytest.raises(SessionError, match="not a session folder"):
        Session.open(tmp_path)


def test_open_refuses_a_damaged_database(tmp_path: Path) -> None:
    path = tmp_path / "s"
    path.mkdir()
    (path / "session.sqlite").write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(SessionError, match="not a usable session database"):
        Session.open(path)


def test_open_refuses_a_session_from_a_newer_workbench(tmp_path: Path) -> None:
    Session.create(tmp_path / "s").close()
    conn = sqlite3.connect(tmp_path / "s" / "session.sqlite")
    conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    conn.close()
    with pytest.raises(SessionError, match="newer than this workbench supports"):
        Session.open(tmp_path / "s")


def test_migrations_run_forward_and_keep_data() -> None:
    conn = sqlite3.connect(":memory:", isolation_level=None)
    assert migrate(conn) == SCHEMA_VERSION
    conn.execute(
        "INSERT INTO logs (name, source_path, source_sha256, format, file, n_samples, rate_hz, t0, ingested_at) "
        "VALUES ('a', 'a.mcap', 'x', 'mcap', 'logs/1.npy', 10, 100, 0, 'now')"
    )

    def add_notes(c: sqlite3.Connection) -> None:
        c.execute("ALTER TABLE logs ADD COLUMN notes TEXT NOT NULL DEFAULT 'none'")

    assert migrate(conn, migrations=(*MIGRATIONS, add_notes)) == SCHEMA_VERSION + 1
    assert schema_version(conn) == SCHEMA_VERSION + 1
    assert conn.execute("SELECT name, notes FROM logs").fetchall() == [("a", "none")]


def test_a_failing_migration_changes_nothing() -> None:
    conn = sqlite3.connect(":memory:", isolation_level=None)
    migrate(conn)

    def broken(c: sqlite3.Connection) -> None:
        c.execute("CREATE TABLE half_done (x INTEGER)")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        migrate(conn, migrations=(*MIGRATIONS, broken))
    assert schema_version(conn) == SCHEMA_VERSION
    assert conn.execute("SELECT name FROM sqlite_master WHERE name = 'half_done'").fetchone() is None


def test_a_new_session_has_no_terrains_and_a_usual_name_gets_its_usual_colour(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s") as s:
        assert s.terrains() == []  # nothing imposed: the robot may walk on ice and wet floors
        ice, grass = s.add_terrain("ice"), s.add_terrain("Grass")
        assert grass.color == "#4caf50" and ice.color not in {"#4caf50"}
        assert s.add_terrain("grass ").name == "grass" and s.terrains()[-1].color != grass.color  # taken: the next


def test_terrains_and_editing_them(session: Session, demo_mcap: Path) -> None:
    assert [t.name for t in session.terrains()] == ["concrete", "grass", "gravel", "mulch", "dirt", "sand"]
    session.add_terrain("snow", color="#ffffff")
    session.rename_terrain("dirt", "soil")
    assert [t.name for t in session.terrains()][-2:] == ["sand", "snow"]
    assert "soil" in [t.name for t in session.terrains()]
    (log,) = session.ingest([demo_mcap])
    session.add_segment(log.id, 0, 10, "snow", author="a")
    with pytest.raises(Exception, match="labels 1 segment"):
        session.remove_terrain("snow")
    session.remove_terrain("grass")
    assert "grass" not in [t.name for t in session.terrains()]


def test_reingesting_the_same_file_keeps_one_log(session: Session, demo_mcap: Path) -> None:
    first = session.ingest([demo_mcap])
    second = session.ingest([demo_mcap])
    assert [x.id for x in first] == [x.id for x in second]
    assert len(session.logs()) == 1
    assert len(list((session.path / "logs").glob("*.npy"))) == 1


def test_leftovers_of_a_crashed_ingest_are_swept(tmp_path: Path) -> None:
    import os
    import time

    Session.create(tmp_path / "s").close()
    stale = tmp_path / "s" / "logs" / ".tmp-dead.npy"
    fresh = tmp_path / "s" / "logs" / ".tmp-live.npy"
    for f in (stale, fresh):
        np.save(f, np.zeros((2, 2), np.float32))
    old = time.time() - 3600
    os.utime(stale, (old, old))
    with ingesting(tmp_path / "s" / "logs"):  # an ingest runs in another process right now
        Session.open(tmp_path / "s").close()
    assert not stale.exists()
    assert fresh.exists()  # might be that ingest's
    Session.open(tmp_path / "s").close()
    assert not fresh.exists()  # no ingest holds the lock: a killed one's, swept at once (issue 52)
    for name in (".tmp-v0001-dead", "v0001"):  # a model save that died before it was registered
        d = tmp_path / "s" / "models" / name
        d.mkdir(parents=True)
        (d / "model.json").write_text("{}")
        os.utime(d, (old, old))
    Session.open(tmp_path / "s").close()
    assert list((tmp_path / "s" / "models").iterdir()) == []


def test_a_session_folder_that_cannot_be_written_gives_a_clear_error(
    tmp_path: Path, demo_mcap: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Disk full while writing a log's array: a clear error, no log listed, no file left behind."""
    s = Session.create(tmp_path / "s")

    def no_space(*args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    # aligned rows are written block by block while aligning: the disk fills on the first block
    monkeypatch.setattr(NpyWriter, "__setitem__", no_space)
    with pytest.raises(SessionError, match="cannot write to the session: No space left on device"):
        s.ingest([demo_mcap])
    monkeypatch.undo()
    assert s.logs() == []
    assert [f.name for f in (tmp_path / "s" / "logs").iterdir()] == [".ingest.lock"]  # no staged file
    (log,) = s.ingest([demo_mcap])  # and the session works afterwards
    assert log.n_samples > 0


def test_a_session_copies_whole_and_the_copy_is_its_own(tmp_path: Path) -> None:
    """``Session.copy_to`` (evaluate loop works on copies): the store by SQLite's backup, logs hard-linked, the copy
    changed without touching the original; a copy never lands on an existing path."""
    import numpy as np
    import pandas as pd

    t = np.arange(2000) / 100.0
    pd.DataFrame({"time": t, "a": np.sin(t)}).to_csv(tmp_path / "w.csv", index=False)
    with Session.create(tmp_path / "s") as s:
        s.add_terrain("grass")
        (log,) = s.ingest([tmp_path / "w.csv"])
        s.add_segment(log.id, 0, 100, "grass", author="a")
        copy = s.copy_to(tmp_path / "copy")
        with pytest.raises(SessionError, match="exists already"):
            s.copy_to(tmp_path / "copy")
    with Session.open(copy) as c, Session.open(tmp_path / "s") as s:
        assert [(g.start, g.stop, g.terrain) for g in c.segments()] == [(0, 100, "grass")]
        np.testing.assert_array_equal(c.samples(log.id), s.samples(log.id))
        c.add_segment(log.id, 200, 300, "grass", author="b")
    with Session.open(tmp_path / "s") as s:
        assert len(s.segments()) == 1  # the original is as it was
    original = next((tmp_path / "s" / "logs").glob("*.npy"))
    assert (copy / "logs" / original.name).stat().st_ino == original.stat().st_ino  # linked, not copied
