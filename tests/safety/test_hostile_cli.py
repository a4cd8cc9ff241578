"""The hostile inputs of issue 52 through the CLI, each in a child process of its own (forked from one that imported
the CLI once: ``tests/fork_server.py``): one line naming the file and the reason,
exit 2, under 1 GB and 20 s, the session unchanged; or, where the input is legitimate, read correctly."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.conftest import new_session, snapshot
from tests.fork_client import TIME_LIMIT_S, run_cli
from tests.safety.hostile_cases import BUILDERS, Case, _csv

PEAK_LIMIT_MB = 1024.0


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """A session with one log, ``walk``, that label files name."""
    folder = tmp_path_factory.mktemp("template")
    s = new_session(folder / "session")
    s.ingest([_csv(folder / "walk.csv", 60.0)])
    s.close()
    return folder / "session"


def _cases(tmp: Path) -> list[Case]:
    return [case for build in BUILDERS for case in build(tmp)]


CASE_NAMES = [build.__name__ for build in BUILDERS]


@pytest.mark.parametrize("build", BUILDERS, ids=CASE_NAMES)
def test_a_hostile_input_ends_in_one_line(build, template: Path, tmp_path: Path, hostile_case) -> None:
    for i, case in enumerate(build(tmp_path)):
        session = tmp_path / f"s-{i}"
        shutil.copytree(template, session)
        before = snapshot(session)
        args = [a.replace("{session}", str(session)) for a in case.args]
        code, out, err, seconds, peak = run_cli(args)
        hostile_case(case.name, seconds, peak, code)
        where = f"{case.name}: rc {code}, stderr {err[-600:]!r}"
        assert "internal error" not in err and "Traceback" not in err, where
        assert code == case.code, where
        assert peak < PEAK_LIMIT_MB, f"{case.name}: peak RSS {peak:.0f} MB"
        assert seconds < TIME_LIMIT_S, f"{case.name}: {seconds:.1f} s"
        if case.check is not None:
            case.check(session, out + err)
            continue
        lines = err.strip().splitlines()
        if "--dry-run" in args and not lines:  # the dry run writes a file's refusal into the mapping it prints
            assert case.says in out, where
        else:
            assert len(lines) == 1, where
            assert case.names in lines[0] and case.says in lines[0], where
        assert snapshot(session) == before, f"{case.name}: refused, yet the session changed"
        assert not list((session / "logs").glob(".tmp-*")), f"{case.name}: a staged file was left"


def test_a_killed_ingests_staged_file_is_swept_at_once_unless_an_ingest_is_live(
    template: Path, tmp_path: Path, hostile_case
) -> None:
    """Before: a staged ``.tmp-*.npy`` was swept only once ten minutes old (a killed ingest left 40 GB meanwhile)."""
    from sessions.ingest_lock import ingesting

    session = tmp_path / "s"
    shutil.copytree(template, session)
    dead = session / "logs" / ".tmp-0123456789abcdef.npy"
    dead.write_bytes(bytes(1 << 20))  # fresh: what a SIGKILLed ingest leaves
    with ingesting(session / "logs"):  # another process's ingest is live: its staged files stay
        code, _, err, _, _ = run_cli(["info", str(session)])
        assert code == 0, err
        assert dead.exists()
    code, _, err, seconds, peak = run_cli(["info", str(session)])
    assert code == 0, err
    assert not dead.exists(), "no ingest is live, yet the staged file stayed"
    hostile_case("a killed ingest's fresh staged file", seconds, peak, code)
