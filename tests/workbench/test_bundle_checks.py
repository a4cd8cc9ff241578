"""The person's checks in an exported bundle (``checks.json``): written as counts, read back as estimates, and any
damaged file named in one line and left out, never a crash (``classify`` writes its predictions all the same)."""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.cycle import ChecksSummary
from workbench.export.bundle_checks import read_checks, write_checks
from workbench.export.file_classify import _checks_lines


def test_the_counts_round_trip_and_no_checks_write_no_file(tmp_path: Path) -> None:
    import labeling

    spot, every = labeling.check_estimate([True, False, False]), labeling.check_estimate([True] * 5 + [False] * 3)
    write_checks(tmp_path, ChecksSummary(spot, None, every))
    back, damaged = read_checks(tmp_path)
    assert damaged is None and back is not None
    assert (back.spot, back.suggested, back.all) == (spot, None, every)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert write_checks(empty, ChecksSummary(None, None, None)) is None and not list(empty.iterdir())
    assert read_checks(empty) == (None, None)


@pytest.mark.parametrize(
    "body",
    ['{"all": [1, 0]}', "[1, 2]", "null", '{"spot": ["a", 3]}', '{"spot": [1, 2, 3]}', '{"spot": [1e400, 3]}',
     '{"spot": 5}', "[" * 50_000, "{", '{"all": [1, 2], "runs": {"a.csv": [3, 2]}}', '{"all": [1, 2], "runs": 4}'],
)  # fmt: skip
def test_a_damaged_checks_file_is_one_warning_line(tmp_path: Path, body: str) -> None:
    (tmp_path / "checks.json").write_text(body)
    checks, lines = _checks_lines(tmp_path, 0.9)
    assert checks is None and len(lines) == 1, lines
    assert lines[0].startswith(f"warning: {tmp_path / 'checks.json'}: damaged (") and "left out" in lines[0]


def test_only_the_checks_of_suggestions_are_said_as_such(tmp_path: Path) -> None:
    (tmp_path / "checks.json").write_text('{"suggested": [3, 5]}')
    _, lines = _checks_lines(tmp_path, 0.9)
    assert lines == [
        "your checks in the session (at export): right on 3 of 5 checks (60 %, 95 % interval 23–88 %), none of them "
        "a spot check (the checks of suggestions are where the model was doubted, and run low)"
    ]
    (tmp_path / "checks.json").write_text('{"spot": [9, 10], "all": [9, 10]}')
    _, lines = _checks_lines(tmp_path, 0.9)  # the card inside the interval: no warning
    assert len(lines) == 1 and lines[0].endswith("right on 9 of 10 spot checks (90 %, 95 % interval 60–98 %)")
