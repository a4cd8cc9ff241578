"""A terrain's names over time (issue 99, item 3): a model or a file of a moment names terrains as they were then."""

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
