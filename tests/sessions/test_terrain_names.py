"""A terrain's names over time: a model or a file of a moment names terrains as they were then."""

from __future__ import annotations

import time
from pathlib import Path

from sessions import Session


def _moment() -> str:
    """A time stamp strictly between what came before and what comes after (renames are stamped to the µs)."""
    from sessions.labels import now

    time.sleep(0.002)
    at = now()
    time.sleep(0.002)
    return at


def test_a_name_given_up_and_taken_again_is_the_terrain_that_held_it_then(tmp_path: Path) -> None:
    s = Session.create(tmp_path / "s")
    s.add_terrain("concrete")
    s.add_terrain("grass")
    at = _moment()  # a model trained here calls them concrete and grass
    s.rename_terrain("concrete", "asphalt")
    s.add_terrain("concrete")  # a new terrain of the old name
    names = s.terrain_names_since(at)
    assert names["concrete"] == "asphalt" and names["asphalt"] == "asphalt" and names["grass"] == "grass"
    later = _moment()
    assert s.terrain_names_since(later)["concrete"] == "concrete"  # a file written after: the new one


def test_a_swap_of_two_names_through_a_third_maps_each_back(tmp_path: Path) -> None:
    s = Session.create(tmp_path / "s")
    s.add_terrain("a")
    s.add_terrain("b")
    at = _moment()
    s.rename_terrain("a", "tmp")
    s.rename_terrain("b", "a")
    s.rename_terrain("tmp", "b")
    names = s.terrain_names_since(at)
    assert (names["a"], names["b"], names["tmp"]) == ("b", "a", "b")


def test_a_file_naming_a_terrain_by_its_old_name_is_refused_naming_the_rename(tmp_path: Path) -> None:
    import numpy as np
    import pandas as pd
    import pytest

    from sessions import LabelError

    s = Session.create(tmp_path / "s")
    s.add_terrain("dirt")
    t = np.arange(500) / 50.0
    pd.DataFrame({"time": t, "a": np.sin(t)}).to_csv(tmp_path / "run.csv", index=False)
    s.ingest([tmp_path / "run.csv"])
    s.rename_terrain("dirt", "soil")
    pd.DataFrame([("run", 1.0, 2.0, "dirt")], columns=["log", "start_s", "end_s", "terrain"]).to_csv(
        tmp_path / "old.csv", index=False
    )
    with pytest.raises(LabelError, match="row 2: terrain 'dirt' was renamed 'soil' in this session"):
        s.import_labels(tmp_path / "old.csv", author="x")
    with pytest.raises(LabelError, match="terrain 'dirt' was renamed 'soil' in this session: --create-terrains"):
        s.import_labels(tmp_path / "old.csv", author="x", create_terrains=True)
    assert [x.name for x in s.terrains()] == ["soil"] and s.segments() == []


def _session_with_a_run(tmp_path: Path, *terrains: str) -> Session:
    import numpy as np
    import pandas as pd

    s = Session.create(tmp_path / "s")
    for name in terrains:
        s.add_terrain(name)
    t = np.arange(1000) / 50.0
    pd.DataFrame({"time": t, "a": np.sin(t)}).to_csv(tmp_path / "run.csv", index=False)
    s.ingest([tmp_path / "run.csv"])
    return s


def _suggested(s: Session, tmp_path: Path, guesses: list[str]) -> tuple[int, Path]:
    """A classifier version and a suggestion file drawn for it, one 1 s piece per guess (as `suggest` records it)."""
    import pandas as pd

    folder = s.next_model_dir()
    folder.mkdir(parents=True)
    version = s.register_model("classifier", folder, config={}, metrics={}).id
    log = s.logs()[0]
    pieces = [(log.id, 50 * i, 50 * (i + 1), version, "suggestion", g) for i, g in enumerate(guesses)]
    s.record_issued(pieces)
    rows = [(log.name, a, b, "", g, k, str(v)) for _, a, b, v, k, g in pieces]
    path = tmp_path / "next.csv"
    cols = ["log", "start_sample", "end_sample", "terrain", "guess", "kind", "classifier"]
    pd.DataFrame(rows, columns=cols).to_csv(path, index=False)
    return version, path


def _fill(path: Path, terrains: list[str]) -> Path:
    import pandas as pd

    rows = pd.read_csv(path, keep_default_na=False, dtype={"classifier": str})
    rows["terrain"] = terrains
    rows.to_csv(path.with_name("filled.csv"), index=False)
    return path.with_name("filled.csv")


def test_a_suggestion_file_filled_in_with_the_names_it_was_written_with_checks_the_same_terrains(
    tmp_path: Path,
) -> None:
    s = _session_with_a_run(tmp_path, "concrete", "grass")
    _, path = _suggested(s, tmp_path, ["concrete", "concrete", "grass", "grass"])
    _moment()
    s.rename_terrain("concrete", "asphalt")
    s.add_terrain("concrete")  # a new terrain of the old name, after the file was written
    # the person fills the file in with the names it shows (two right, two wrong)
    done = s.import_labels(_fill(path, ["concrete", "grass", "grass", "concrete"]), author="me")
    assert done.checks == 4
    assert [c.right for c in s.checks()] == [True, False, True, False]
    spans = [(g.start, g.stop, g.terrain) for g in s.segments()]  # the two grass pieces side by side are one label
    assert spans == [(0, 50, "asphalt"), (50, 150, "grass"), (150, 200, "asphalt")]


def test_a_suggestion_file_from_before_a_swap_of_names_reads_each_name_back(tmp_path: Path) -> None:
    s = _session_with_a_run(tmp_path, "a", "b")
    _, path = _suggested(s, tmp_path, ["a", "b"])
    _moment()
    s.rename_terrain("a", "tmp")
    s.rename_terrain("b", "a")
    s.rename_terrain("tmp", "b")
    s.import_labels(_fill(path, ["a", "b"]), author="me")  # both right, as the names were when it was written
    assert [c.right for c in s.checks()] == [True, True]
    assert [g.terrain for g in s.segments()] == ["b", "a"]


def test_the_sessions_own_export_from_before_a_rename_imports_back_as_the_same_labels(tmp_path: Path) -> None:
    s = _session_with_a_run(tmp_path, "concrete", "dirt")
    log = s.logs()[0]
    s.add_segment(log_id=log.id, start=0, stop=100, terrain="concrete", author="me")
    s.add_segment(log_id=log.id, start=200, stop=300, terrain="dirt", author="me")
    s.export_labels(tmp_path / "before.csv")
    _moment()
    s.rename_terrain("concrete", "asphalt")
    s.add_terrain("concrete")
    s.rename_terrain("dirt", "soil")
    before = s.segments()
    done = s.import_labels(tmp_path / "before.csv", author="me")
    assert (done.rows, done.already, done.segments) == (2, 2, ())
    again = s.import_labels(tmp_path / "before.csv", author="me", create_terrains=True)  # no second dirt either
    assert again.already == 2 and [t.name for t in s.terrains()] == ["asphalt", "soil", "concrete"]
    assert s.segments() == before
